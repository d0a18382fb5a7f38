"""Every call into pymeshlab, in one thread of its own that lives as long as the process.

``import pymeshlab`` loads MeshLab's plugins through Qt, and Qt ties every plugin object (and
its ``QPluginLoader``) to the ``QThreadData`` of the importing thread. MeshLab's global
``PluginManager`` is destroyed by the C++ exit handlers, after Python has finalised: it unloads
the plugins and destroys the loaders, and when the importing thread has already ended by then
(any Python thread other than the main one: a ``threading.Thread``, a Dask worker's thread, or
the worker of a ``ThreadPoolExecutor``, which Python joins at shutdown) the last plugin
deleted frees that ``QThreadData`` and the next loader's destructor decrements its reference
count in freed memory (valgrind: "Invalid read of size 4 ... QThreadData::deref() ...
~QPluginLoader ... PluginManager::~PluginManager ... exit", in a 120-byte block freed by
``~IoX3DPlugin``). The decrement lands on the free-list pointer of the freed chunk, and glibc
aborts at the next consolidation of that arena ("malloc_consolidate(): unaligned fastbin
chunk detected", Qt 5 as bundled by pymeshlab 2025.7). Whether it aborts depends on the heap's
layout only: with numba's compiler (LLVM) run in the same thread before, always; otherwise
sometimes, at exit.

So the functions of this package that call pymeshlab are :func:`confined`: they run in one
dedicated daemon thread that imports pymeshlab first and is never joined nor ended, so the
plugins' thread is still alive when the exit handlers destroy them (pymeshlab imported in the
main thread is as safe: the main thread is the one that runs the exit handlers). MeshLab's
work is serialised across the caller's threads, a small cost beside the safety.

Written here: a workaround for a fault of pymeshlab and Qt together, documented by neither.
"""

from __future__ import annotations

import functools
import os
import queue
import threading
from collections.abc import Callable
from concurrent.futures import Future
from typing import TypeVar

__all__ = ["confined"]

_PREFIX = "pymeshlab"

Result = TypeVar("Result")

_LOCK = threading.Lock()
_TASKS: queue.SimpleQueue | None = None


def _serve(tasks: queue.SimpleQueue) -> None:
    """The pymeshlab thread: imports pymeshlab (its plugins are this thread's), then runs tasks
    for ever (a daemon: never joined, so never ended before the process's exit handlers)."""
    try:
        import pymeshlab  # noqa: F401
    except Exception:  # noqa: BLE001 - the confined function raises it again where it imports
        pass
    while True:
        future, function, args, kwargs = tasks.get()
        if not future.set_running_or_notify_cancel():
            continue
        try:
            future.set_result(function(*args, **kwargs))
        except BaseException as err:  # noqa: BLE001 - handed to the caller
            future.set_exception(err)
        del future, function, args, kwargs  # drop the task's references while waiting


def _tasks() -> queue.SimpleQueue:
    """The queue of the pymeshlab thread, started on first use."""
    global _TASKS
    with _LOCK:
        if _TASKS is None:
            tasks: queue.SimpleQueue = queue.SimpleQueue()
            threading.Thread(target=_serve, args=(tasks,), name=f"{_PREFIX}-0", daemon=True).start()
            _TASKS = tasks
        return _TASKS


def _forget_after_fork() -> None:
    # A forked child has no copy of the thread: it starts its own on first use.
    global _TASKS, _LOCK
    _TASKS = None
    _LOCK = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_after_fork)


def confined(function: Callable[..., Result]) -> Callable[..., Result]:
    """``function`` run in the pymeshlab thread (directly when called from it: no deadlock)."""

    @functools.wraps(function)
    def in_thread(*args, **kwargs) -> Result:
        if threading.current_thread().name.startswith(_PREFIX):
            return function(*args, **kwargs)
        future: Future = Future()
        _tasks().put((future, function, args, kwargs))
        return future.result()

    return in_thread
