"""The paper's nearly uniform quantizer Q_T (section 4, step (8)).

``Q_T(x) = 0`` if ``|x| <= T``, else ``sign(x) (q + 1/2) T`` for ``q T <= |x| < (q + 1) T``:
a dead zone of width ``2T`` and bins of width ``T`` reconstructed at their middle. The
integer that is entropy-coded is the signed bin index ``sign(x) q`` (0 in the dead zone).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["quantize", "dequantize", "bin_index", "quantization_error", "bin_and_error"]

#: Largest bin index the bitstream accepts: keeps every integer well inside int32.
MAX_INDEX = 2**30
#: Where inside its bin a value is reconstructed: ``(q + RECONSTRUCTION) T``.
RECONSTRUCTION = 0.5


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
    q = np.floor(np.abs(x) / threshold)
    q[np.abs(x) <= threshold] = 0
    if q.size and q.max() >= MAX_INDEX:
        raise ValueError(f"threshold {threshold:g} is too small for values of this magnitude")
    return (np.sign(x) * q).astype(np.int32)


def dequantize(q: np.ndarray, threshold: float) -> np.ndarray:
    """Reconstruction ``sign(q) (|q| + 1/2) T`` of signed bin indices (0 stays 0)."""
    q = q.astype(np.float64)
    return np.sign(q) * (np.abs(q) + RECONSTRUCTION) * threshold


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
