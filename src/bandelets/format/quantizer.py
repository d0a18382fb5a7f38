"""The paper's nearly uniform quantizer Q_T (section 4, step (8)), and its contract.

``Q_T(x) = 0`` if ``|x| <= T``, else ``sign(x) (q + 1/2) T`` for ``q T <= |x| < (q + 1) T``:
a dead zone of width ``2T`` and bins of width ``T`` reconstructed at their middle
(:data:`RECONSTRUCTION`). The integer that
is entropy-coded is the signed bin index ``sign(x) q`` (0 in the dead zone).

The contract between the encoder and the decoder, in this one module:

* :func:`quantize` gives the bins, :func:`dequantize` the values the decoder reconstructs;
* the encoder may then move a value between 0 and +-1 (rate-distortion optimised
  quantization, :func:`bandelets.search.quantization.optimise_bins`): a value of bin +-1 may be coded as 0,
  a dead-zone value
  above :data:`PROMOTE_ABOVE` T as +-1;
* so a decoder may assume no more than :func:`bin_bounds`: the interval each bin's value came
  from (the restoration, :mod:`bandelets.restore.restoration`, keeps every coefficient inside it).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "PROMOTE_ABOVE",
    "RECONSTRUCTION",
    "ZERO_UP_TO",
    "quantize",
    "dequantize",
    "bin_bounds",
    "clip_into_bins",
    "bin_index",
    "quantization_error",
    "bin_and_error",
]

#: Largest bin index the bitstream accepts: keeps every integer well inside int32.
MAX_INDEX = 2**30
#: Where inside its bin a value is reconstructed: ``(q + RECONSTRUCTION) T``. The paper takes
#: the middle (1/2). The coefficients inside a bin decrease with magnitude, and their mean sits at
#: 0.42 to 0.47 of the bin on the generated normal maps, but the restoration starts from these
#: values and moves them inside their bins: with it, the middle gained +0.12 dB BD-PSNR over 0.44
#: on the 256 x 256 crease map, +0.06 on the bumps, +0.02 on the acacia door and the bunny
#: normals, -0.01 on the lava flow (format version 11; 0.47: half of that, 0.56: mixed).
# Compiled into the kernels of bandeletize.py and lagrangian.py as a constant: numba's cache does
# not see a change here, so delete src/bandelets/__pycache__/*.nb[ic] after changing it
# (tests/test_reference.py fails on a stale cache).
RECONSTRUCTION = 0.5
#: Dead-zone values above this many T may be coded as +-1 by the encoder (the dead zone is T).
PROMOTE_ABOVE = 0.7
#: A value of bin +-1 (below 2T) may be coded as 0 by the encoder: a 0 may hide up to this many T.
ZERO_UP_TO = 2.0


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


@njit(cache=True, nogil=True, error_model="numpy")  # T = 0 divides to inf, then refused
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
    """Reconstruction ``sign(q) (|q| + RECONSTRUCTION) T`` of signed bin indices (0 stays 0).

    Examples
    --------
    >>> q = quantize(np.array([0.5, 1.0, 1.5, -2.7]), 1.0)  # a dead zone of 2T, then bins of T
    >>> q
    array([ 0,  0,  1, -2], dtype=int32)
    >>> dequantize(q, 1.0)
    array([ 0. ,  0. ,  1.5, -2.5])
    """
    q = np.asarray(q)
    out = np.empty(q.shape)
    _dequantize(q.ravel(), float(threshold), out.reshape(-1))
    return out


@njit(cache=True, nogil=True)
def _dequantize(q, threshold, out):
    for i in range(q.shape[0]):
        v = float(q[i])
        out[i] = np.sign(v) * (abs(v) + RECONSTRUCTION) * threshold


@njit(cache=True, nogil=True, inline="always")
def bin_and_error(x: float, threshold: float) -> tuple[int, float]:
    """:func:`bin_index` and :func:`quantization_error` of one value, with one division."""
    a = abs(x)
    # Both branches computed and one selected: no mispredicted jumps in the search's loops.
    dead = a <= threshold
    m = 0 if dead else int(a / threshold)
    e = a if dead else a - (m + RECONSTRUCTION) * threshold
    return m, e * e


@njit(cache=True, nogil=True, inline="always")
def bin_index(x: float, threshold: float) -> int:
    """``|Q_T|`` bin index of one value: 0 in the dead zone, else ``floor(|x| / T)``."""
    return bin_and_error(x, threshold)[0]


@njit(cache=True, nogil=True, inline="always")
def quantization_error(x: float, threshold: float) -> float:
    """Squared error ``(x - Q_T(x))**2`` of one value."""
    return bin_and_error(x, threshold)[1]


def bin_bounds(q: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Interval each coefficient of bin index ``q`` may have come from.

    Parameters
    ----------
    q : ndarray of int
        Signed bin indices (:func:`bandelets.format.quantizer.quantize`, after the encoder's choices
        between 0 and +-1).
    threshold : float
        ``T``.

    Returns
    -------
    low, high : ndarray of float64, shape of ``q``
        ``[-2T, 2T]`` for 0, ``[PROMOTE_ABOVE T, 2T]`` for 1, ``[|q| T, (|q| + 1) T]`` above, with the
        sign of ``q``.
    """
    a = np.abs(q).astype(np.float64)
    low = np.where(a == 0, -ZERO_UP_TO, np.where(a == 1, PROMOTE_ABOVE, a)) * threshold
    high = np.where(a <= 1, ZERO_UP_TO, a + 1.0) * threshold
    negative = q < 0
    return np.where(negative, -high, low), np.where(negative, -low, high)


def clip_into_bins(c: np.ndarray, q: np.ndarray, threshold: float) -> None:
    """Clip every value of ``c`` into the interval of its bin index (:func:`bin_bounds` of ``q``),
    in place, without making the bounds: the same numbers as ``np.clip(c, *bin_bounds(q, T))``.

    Parameters
    ----------
    c : ndarray of float64, shape (H, W)
    q : ndarray of int, shape (H, W)
    threshold : float
    """
    _clip_into_bins(c, q, float(threshold))


@njit(cache=True, nogil=True)
def _clip_into_bins(c, q, threshold):
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            a = abs(q[i, j])
            low = (-ZERO_UP_TO if a == 0 else (PROMOTE_ABOVE if a == 1 else float(a))) * threshold
            high = (ZERO_UP_TO if a <= 1 else a + 1.0) * threshold
            if q[i, j] < 0:
                low, high = -high, -low
            c[i, j] = min(max(c[i, j], low), high)
