"""Every call into pymeshlab, in one thread of its own.

pymeshlab run in a thread that has also run numba's compiled code corrupts the heap, and glibc
aborts the process at exit ("malloc_consolidate(): unaligned fastbin chunk detected"; numba
0.6x, pymeshlab 2025.7: reproduced by :func:`bandelets.surfaces.codec.decode_mesh` in a
``threading.Thread``, where its restoration and its decimation then share the thread). The
main thread is not affected, but a Dask worker, or a user's thread pool, runs tasks in other
threads. So the functions of this package that call pymeshlab are :func:`confined`: they run
in one dedicated thread, which never runs numba code, and their caller waits. MeshLab's work is
serialised across the caller's threads, a small cost beside the safety.

Written here: a workaround for a fault of the two libraries together, documented by neither.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

__all__ = ["confined"]

_PREFIX = "pymeshlab"
_THREAD = ThreadPoolExecutor(max_workers=1, thread_name_prefix=_PREFIX)

Result = TypeVar("Result")


def confined(function: Callable[..., Result]) -> Callable[..., Result]:
    """``function`` run in the pymeshlab thread (directly when called from it: no deadlock)."""

    @functools.wraps(function)
    def in_thread(*args, **kwargs) -> Result:
        if threading.current_thread().name.startswith(_PREFIX):
            return function(*args, **kwargs)
        return _THREAD.submit(function, *args, **kwargs).result()

    return in_thread
