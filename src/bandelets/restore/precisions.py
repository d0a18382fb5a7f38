"""Both precisions of the kernels whose type a file chooses, compiled together (issue 40).

The restoration's images are float32, or float64 for extreme thresholds and values
(:data:`bandelets.restore.restoration.SINGLE_UP_TO`), and a Riesz pair is turned in float64 below
:data:`bandelets.transform.riesz.SINGLE_FROM`: the file's threshold picks the specialization of
:func:`bandelets.restore.restoration._rows` (and the kernels it calls), ``_extrapolate`` and
:func:`bandelets.transform.riesz._turn_spectra`. A process that had only ever seen ordinary files then
compiled the float64 ones at the decode of a file asking for them: a 253-byte file with a
threshold of 1e30 cost 13.7 s of CPU, outside any work bound, in every process with an empty or
read-only kernel cache.

:func:`compile_both` runs each of them once on a few samples of each precision, the first time
the decoder restores a file or turns a Riesz pair (:func:`bandelets.codec.decoder.restorations`): both
are compiled (or loaded from numba's cache) with the others, so which one a file asks for changes
nothing of the time its decode takes.
"""

from __future__ import annotations

import threading

import numpy as np

from ..transform import riesz
from . import restoration

__all__ = ["compile_both"]

_DONE: list[bool] = []
_LOCK = threading.Lock()


def compile_both() -> None:
    """Run the kernels of both precisions on tiny arrays, once per process (thread-safe)."""
    if _DONE:
        return
    with _LOCK:
        if _DONE:
            return
        for dtype in (np.float32, np.float64):
            x = np.zeros((3, 4, 4), dtype)
            out, previous = np.zeros_like(x), np.zeros_like(x)
            # The argument types of an iteration (bandelets.restore.restoration.iterate): a step with the
            # momentum, every term across the folds, the unit vectors.
            restoration._in_halves(x, (1.0, 1.0, 1.0, 1.0), 0.1, out, previous, 0.5, 4, 4, 2)
            restoration._extrapolate(out.reshape(-1), x.reshape(-1), x.dtype.type(0.5))
            riesz.inverse(*riesz.forward(x[0], x[1]))
        _DONE.append(True)
