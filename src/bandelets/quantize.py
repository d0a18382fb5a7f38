"""The paper's nearly uniform quantizer Q_T (section 4, step (8)).

``Q_T(x) = 0`` if ``|x| <= T``, else ``sign(x) (q + 1/2) T`` for ``q T <= |x| < (q + 1) T``:
a dead zone of width ``2T`` and bins of width ``T`` reconstructed at their middle. Here the
reconstruction point is :data:`RECONSTRUCTION` (a little below the middle), and the encoder
may move a value between 0 and +-1 (rate-distortion optimised quantization, in
:mod:`bandelets.encoder`). The integer that is entropy-coded is the signed bin index
``sign(x) q`` (0 in the dead zone).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["PROMOTE_ABOVE", "quantize", "dequantize", "bin_index", "quantization_error", "bin_and_error"]

#: Largest bin index the bitstream accepts: keeps every integer well inside int32.
MAX_INDEX = 2**30
#: Where inside its bin a value is reconstructed: ``(q + RECONSTRUCTION) T``. The paper takes
#: the middle (1/2); the coefficients inside a bin decrease with magnitude, and their mean
#: sits at 0.42 to 0.47 of the bin on the generated normal maps (0.44: +0.06 dB BD-PSNR).
# Compiled into the kernels of bandeletize.py and lagrangian.py as a constant: numba's cache does
# not see a change here, so delete src/bandelets/__pycache__/*.nb[ic] after changing it
# (tests/test_reference.py fails on a stale cache).
RECONSTRUCTION = 0.44
#: Dead-zone values above this many T may be coded as +-1 by the encoder (the dead zone is T).
PROMOTE_ABOVE = 0.7


def quantize(x: np.ndarray, threshold: float) -> np.ndarray:
    """Signed bin indices of ``x``: ``sign(x) * floor(|x| / T)`` outside the dead zone, else 0.

    Parameters
    ----------
    x : ndarray of float
    threshold : float, > 0

    Returns
    -------
    ndarray of int32, same shape as ``x``.
    """
    x = np.asarray(x, np.float64)
    q = np.empty(x.shape, np.int32)
    if _quantize(x.ravel(), float(threshold), q.reshape(-1)) >= MAX_INDEX:
        raise ValueError(f"threshold {threshold:g} is too small for values of this magnitude")
    return q


@njit(cache=True, error_model="numpy")  # T = 0 divides to inf, then refused
def _quantize(x, threshold, out):
    """Fills ``out`` with the bin indices of ``x``; returns the largest magnitude, unless it
    reaches MAX_INDEX (then returns it at once, ``out`` unfinished)."""
    top = 0.0
    for i in range(x.shape[0]):
        a = abs(x[i])
        m = 0.0 if a <= threshold else np.floor(a / threshold)
        if m >= MAX_INDEX:
            return m
        top = max(top, m)
        out[i] = np.int32(np.sign(x[i]) * m)
    return top


def dequantize(q: np.ndarray, threshold: float) -> np.ndarray:
    """Reconstruction ``sign(q) (|q| + RECONSTRUCTION) T`` of signed bin indices (0 stays 0)."""
    q = np.asarray(q)
    out = np.empty(q.shape)
    _dequantize(q.ravel(), float(threshold), out.reshape(-1))
    return out


@njit(cache=True)
def _dequantize(q, threshold, out):
    for i in range(q.shape[0]):
        v = float(q[i])
        out[i] = np.sign(v) * (abs(v) + RECONSTRUCTION) * threshold


@njit(cache=True, inline="always")
def bin_and_error(x: float, threshold: float) -> tuple[int, float]:
    """:func:`bin_index` and :func:`quantization_error` of one value, with one division."""
    a = abs(x)
    # Both branches computed and one selected: no mispredicted jumps in the search's loops.
    dead = a <= threshold
    m = 0 if dead else int(a / threshold)
    e = a if dead else a - (m + RECONSTRUCTION) * threshold
    return m, e * e


@njit(cache=True, inline="always")
def bin_index(x: float, threshold: float) -> int:
    """``|Q_T|`` bin index of one value: 0 in the dead zone, else ``floor(|x| / T)``."""
    return bin_and_error(x, threshold)[0]


@njit(cache=True, inline="always")
def quantization_error(x: float, threshold: float) -> float:
    """Squared error ``(x - Q_T(x))**2`` of one value."""
    return bin_and_error(x, threshold)[1]
