"""One BLAS thread while the library runs threads of its own (issue 36).

The codec runs its compiled kernels on threads of its own (:func:`bandelets.restoration.workers`,
the row bands of the loop filter and of the measures, the tiles of a large image, the files of a
batch). A BLAS library that starts as many threads again for a product oversubscribes the cores,
and on a shared machine its spinning threads stall one another: the loop filter's least squares
took 15 of 22 s of an encode with the other core busy (issue 36). Within :func:`one_blas_thread`,
every BLAS the process has loaded (OpenBLAS, MKL, BLIS, as threadpoolctl finds them) runs one
thread; a busy machine then slows the codec by its share of the cores, not by stalls.

Calls nest and may come from several threads at once (a Dask worker encoding two files): the
limit is set by the first to enter and the original limits restored by the last to leave, each
taking control of OpenBLAS's process-wide limit first (threadpoolctl 3.8 lets only the thread that
first set it change it again: a limit set from a Dask worker's thread would otherwise be a no-op
once the main thread has set one). The libraries are those loaded when the first call enters.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["one_blas_thread", "blas_threads"]

_LOCK = threading.Lock()
_depth = 0
_limiter: Any = None
_controller: Any = None


def _blas_controller() -> Any:
    """threadpoolctl's controller of the thread pools loaded in the process, made once (it reads
    the loaded libraries, a few milliseconds), or None without threadpoolctl."""
    global _controller
    if _controller is None:
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:  # a dependency; without it the limit is only not set
            _controller = False
        else:
            _controller = ThreadpoolController()
    return _controller or None


def _take_control() -> None:
    """Let this thread set OpenBLAS's limit (threadpoolctl from 3.8 ignores the other threads'
    calls; our own calls are serialised by :data:`_LOCK`)."""
    try:
        from threadpoolctl import OpenBLASController
    except ImportError:
        return
    clear = getattr(OpenBLASController, "clear_controlling_thread", None)
    if clear is not None:
        clear(force=True)


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Within this context (or a function it decorates), BLAS runs one thread.

    Examples
    --------
    >>> import bandelets.runtime.blas as b
    >>> with b.one_blas_thread():
    ...     inside = b.blas_threads()
    >>> all(n == 1 for n in inside)
    True
    """
    global _depth, _limiter
    with _LOCK:
        if _depth == 0:
            controller = _blas_controller()
            _take_control()
            _limiter = None if controller is None else controller.limit(limits=1, user_api="blas")
        _depth += 1
    try:
        yield
    finally:
        with _LOCK:
            _depth -= 1
            if _depth == 0 and _limiter is not None:
                _take_control()
                _limiter.restore_original_limits()
                _limiter = None


def blas_threads() -> list[int]:
    """The threads of each BLAS the process has loaded (empty without threadpoolctl)."""
    controller = _blas_controller()
    if controller is None:
        return []
    return [int(pool.num_threads) for pool in controller.select(user_api="blas").lib_controllers]
