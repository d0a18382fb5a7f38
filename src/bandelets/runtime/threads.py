"""The process's threads: its cores, one pool of worker threads, and a bounded map over items.

Written here because the standard library's :class:`~concurrent.futures.ThreadPoolExecutor` starts
threads at every ``with`` block and ``Executor.map`` submits every item at once (no memory bound);
the codec's kernels let go of the GIL (numba ``nogil``), so threads share the work of one image.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

__all__ = ["BY_ROWS_FROM", "CORES", "by_rows", "each", "one_of_many", "spare_core", "thread_map", "workers"]

#: Cores this process may run on (its CPU affinity): the kernels that split their rows in threads ask.
CORES = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()
#: ``item``: set in the threads of a :func:`thread_map`, which share the cores among its items.
_MAPPED = threading.local()
if hasattr(os, "register_at_fork"):  # a forked child has the pool but not its thread: a new one
    os.register_at_fork(after_in_child=lambda: globals().update(_POOL=None, _POOL_LOCK=threading.Lock()))


def workers() -> ThreadPoolExecutor:
    """The process's worker threads, one fewer than :data:`CORES` (the calling thread takes a share
    of the work): the second half of the rows of an iteration, the other channels of a transform
    (:func:`bandelets.codec.decoder.channel_transforms`), half of the rows of the encoder's measure
    (:func:`bandelets.metrics.psnr_of_channels`). Made once, not a thread started at every call
    (with the measure's float64 copy, 15 % of the CPU time of the encoder's restoration search at
    512 x 512 on a loaded 2-core machine: 362-380 ms before, 311-321 ms after, same files)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=max(CORES - 1, 1), thread_name_prefix="bandelets")
        return _POOL


def thread_map(function, items, workers: int = 2):
    """``function`` over ``items`` in ``workers`` threads, results in order, at most ``workers``
    items in flight (the memory bound)."""
    if workers < 2:
        yield from map(function, items)
        return

    def marked(item):
        _MAPPED.item = True
        return function(item)

    with ThreadPoolExecutor(max_workers=workers) as pool:
        items = iter(items)
        pending = [pool.submit(marked, item) for _, item in zip(range(workers), items, strict=False)]
        while pending:
            result = pending.pop(0).result()
            for item in items:
                pending.append(pool.submit(marked, item))
                break
            yield result


def each(function, items, threaded: bool = True) -> list:
    """``[function(item) for item in items]``, the first item in the calling thread and the others in
    the process's :func:`workers` when ``threaded`` (the caller's rule: large enough to pay for the
    hand-over, about 0.1 ms) and there is a second core: the channels of one image, which the
    kernels transform without the GIL. Serial inside a worker thread, which would otherwise wait
    on the pool it is part of."""
    items = list(items)
    if not threaded or len(items) < 2 or CORES < 2 or _in_pool():
        return [function(item) for item in items]
    first, *others = items
    futures = [workers().submit(function, item) for item in others]
    return [function(first), *(future.result() for future in futures)]


def _in_pool() -> bool:
    """Whether the calling thread is one of the :func:`workers` (which must not wait on its own pool)."""
    return threading.current_thread().name.startswith("bandelets")


def one_of_many() -> bool:
    """Whether the calling thread already shares the cores with others of the library's: one of the
    :func:`workers` or an item of a :func:`thread_map`."""
    return _in_pool() or getattr(_MAPPED, "item", False)


def spare_core() -> bool:
    """Whether work handed to the :func:`workers` would run on a core of its own: a second core, and
    a calling thread that does not already share them (:func:`one_of_many`)."""
    return CORES > 1 and not one_of_many()


#: Values from which :func:`by_rows` splits the rows in two threads (below, the hand-over costs more).
BY_ROWS_FROM = 2**20


def by_rows(function, array: np.ndarray) -> np.ndarray:
    """``function(array)`` for a ``function`` that makes each row of its result from the same row of
    ``array`` alone (numpy's elementwise functions, which let go of the GIL on large arrays): from
    :data:`BY_ROWS_FROM` values on, the second half of the rows in a worker thread, the same numbers."""
    rows = array.shape[0]
    if array.size < BY_ROWS_FROM or rows < 2 or not spare_core():
        return function(array)
    half = rows // 2
    second = workers().submit(function, array[half:])
    first = function(array[:half])
    out = np.empty((rows, *first.shape[1:]), first.dtype)
    out[:half] = first
    del first
    out[half:] = second.result()
    return out
