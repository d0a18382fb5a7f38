"""Steps (5) to (7) and (9) of the paper: bandeletization of one wavelet subband.

Inside every leaf square of the quadtree that has a direction ``d``, the wavelet
coefficients are read in the order of ``d`` (:func:`bandelets.geometry.directions`),
transformed by a full orthonormal 1D Haar transform (coarse first: approximation, then
the coarsest detail, ..., the finest details), and written back into the square in zig-zag
order. Squares without a direction (``d = NULL``, stored as -1) keep their wavelet
coefficients. Both steps are permutations and orthonormal maps, so the whole is an
orthonormal change of basis of the subband, inverted exactly by :func:`debandeletize`.

All squares sharing a width and a direction are gathered into one ``(n_squares, L*L)``
array and transformed together.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .geometry import directions, zigzag

__all__ = ["haar_inplace", "haar_rows", "ihaar_rows", "bandeletize", "debandeletize"]

_SQRT_HALF = np.sqrt(0.5)


@njit(cache=True)
def haar_inplace(v: np.ndarray, tmp: np.ndarray) -> None:
    """Full orthonormal Haar transform of ``v`` (length a power of two), in place.

    The result is laid out ``[a, d_coarsest, d_2 (2 values), ..., d_finest (n/2 values)]``:
    the 1D scale of index ``i >= 1`` is ``floor(log2(i))``.
    """
    n = v.shape[0]
    while n > 1:
        half = n // 2
        for i in range(half):
            a = v[2 * i]
            b = v[2 * i + 1]
            tmp[i] = (a + b) * _SQRT_HALF
            tmp[half + i] = (a - b) * _SQRT_HALF
        v[:n] = tmp[:n]
        n = half


@njit(cache=True)
def _ihaar_inplace(v: np.ndarray, tmp: np.ndarray) -> None:
    size = v.shape[0]
    n = 1
    while n < size:
        for i in range(n):
            a = v[i]
            d = v[n + i]
            tmp[2 * i] = (a + d) * _SQRT_HALF
            tmp[2 * i + 1] = (a - d) * _SQRT_HALF
        n *= 2
        v[:n] = tmp[:n]


@njit(cache=True)
def haar_rows(x: np.ndarray) -> np.ndarray:
    """:func:`haar_inplace` applied to every row of a 2D array (returns a new array)."""
    out = x.copy()
    tmp = np.empty(x.shape[1])
    for r in range(x.shape[0]):
        haar_inplace(out[r], tmp)
    return out


@njit(cache=True)
def ihaar_rows(x: np.ndarray) -> np.ndarray:
    """Inverse of :func:`haar_rows`."""
    out = x.copy()
    tmp = np.empty(x.shape[1])
    for r in range(x.shape[0]):
        _ihaar_inplace(out[r], tmp)
    return out


def _square_groups(tree):
    """Yield ``(width, direction, flat indices of the squares' samples)`` per group.

    The indices are into the subband raveled row-major, shape ``(n_squares, L*L)``, row-major
    inside each square.
    """
    top, left, widths, dirs = tree.leaves()
    for width in np.unique(widths):
        for d in np.unique(dirs[(widths == width) & (dirs >= 0)]):
            pick = (widths == width) & (dirs == d)
            offsets = np.arange(width)
            rows = top[pick, None, None] + offsets[None, :, None]
            cols = left[pick, None, None] + offsets[None, None, :]
            yield int(width), int(d), rows, cols


def bandeletize(subband: np.ndarray, tree) -> np.ndarray:
    """Bandelet coefficients of one subband for a given quadtree and directions.

    Parameters
    ----------
    subband : ndarray, shape (h, w), float64
        Wavelet coefficients of one subband.
    tree : bandelets.quadtree.Quadtree
        Leaf squares and their directions.

    Returns
    -------
    ndarray, shape (h, w): the wavelet coefficients with every square that has a direction
    replaced by its 1D Haar coefficients in zig-zag order.
    """
    out = subband.copy()
    for width, d, rows, cols in _square_groups(tree):
        order = directions(width)[1][d]
        squares = subband[rows, cols].reshape(len(rows), -1)
        coeffs = haar_rows(np.ascontiguousarray(squares[:, order]))
        stored = np.empty_like(coeffs)
        stored[:, zigzag(width)] = coeffs
        out[rows, cols] = stored.reshape(rows.shape[0], width, width)
    return out


def debandeletize(coefficients: np.ndarray, tree) -> np.ndarray:
    """Inverse of :func:`bandeletize`: wavelet coefficients of the subband."""
    out = coefficients.copy()
    for width, d, rows, cols in _square_groups(tree):
        order = directions(width)[1][d]
        stored = coefficients[rows, cols].reshape(len(rows), -1)
        signal = ihaar_rows(np.ascontiguousarray(stored[:, zigzag(width)]))
        squares = np.empty_like(signal)
        squares[:, order] = signal
        out[rows, cols] = squares.reshape(rows.shape[0], width, width)
    return out
