"""Kernels compiled for the signatures they are given, on their first call.

Numba compiles a kernel anew for each memory layout it is handed: the lifting passes take
row-major blocks, their transposes (column-major) and corners of larger arrays (strided), so each
pass was compiled three times on a first run. A :class:`Kernel` is compiled on its first call for
the signatures it is given and never again: an array of another layout is passed as one of a
layout the signatures allow (``f8[:, :]``: any). The lifting keeps two of its three compilations
(``transform/lifting.py``, ``_layouts``): 13 s of CPU instead of 17 for its first analysis and
synthesis of a 512 x 512 map. Compiling at the first call rather than at import (numba's
``njit(signature)``) keeps a run that never calls the kernel from compiling or loading it, and lets
:mod:`bandelets.runtime.compilation` hear the compilation.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from numba import njit

__all__ = ["Kernel", "kernel"]


class Kernel:
    """``njit(cache=True, nogil=True)`` of ``function`` compiled, at its first call, for
    ``signatures`` only (numba's cache holds them as any kernel's).

    Parameters
    ----------
    function : callable
        The Python function numba compiles.
    signatures : sequence of str
        Numba signatures (``"void(f8[:, :], b1)"``); a call whose arguments match none exactly is
        converted to the first they convert to (a row-major array to an array of any layout).
    """

    __slots__ = ("dispatcher", "signatures", "_ready", "_lock")

    def __init__(self, function: Callable, signatures: tuple[str, ...]):
        self.dispatcher = njit(cache=True, nogil=True)(function)
        self.signatures = signatures
        self._ready = False
        self._lock = threading.Lock()  # the restoration's threads may make the first call together

    def __call__(self, *args: Any) -> Any:
        if not self._ready:
            with self._lock:
                # NUMBA_DISABLE_JIT=1 (the decoder's bounds checks, tests/test_reliability_issue40.py):
                # njit gave back the Python function itself, nothing to compile.
                if not self._ready and hasattr(self.dispatcher, "compile"):
                    for signature in self.signatures:
                        self.dispatcher.compile(signature)
                    self.dispatcher.disable_compile()
                self._ready = True
        return self.dispatcher(*args)


def kernel(*signatures: str) -> Callable[[Callable], Kernel]:
    """Decorator: a :class:`Kernel` of the function for ``signatures``."""
    return lambda function: Kernel(function, signatures)
