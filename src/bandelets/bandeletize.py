"""Steps (5) to (7) and (9) of the paper: bandeletization of one wavelet subband.

Inside every leaf square of the quadtree that has a direction ``d``, the wavelet
coefficients are read in the order of ``d`` (:func:`bandelets.geometry.directions`),
transformed by a full orthonormal 1D wavelet transform (coarse first: approximation,
then the coarsest detail, ..., the finest details): Haar, as in the paper, or Alpert's
multiwavelet with two vanishing moments, the paper's choice for its theorem, which also
cancels the linear part of a blurred crease profile, and written back into the square in zig-zag
order. Squares without a direction (``d = NULL``, stored as -1) keep their wavelet
coefficients. Both steps are permutations and orthonormal maps, so the whole is an
orthonormal change of basis of the subband, inverted exactly by :func:`debandeletize`.

All squares sharing a width and a direction are gathered into one ``(n_squares, L*L)``
array and transformed together.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from numba import njit

from .geometry import directions, zigzag

__all__ = [
    "TRANSFORMS_1D",
    "alpert_matrices",
    "multiwavelet_inplace",
    "transform_rows",
    "bandeletize",
    "debandeletize",
]

#: 1D transforms along the reordered samples, by the order ``k`` of their polynomial
#: reproduction: Haar (constants) and Alpert's multiwavelet with ``k = 2`` (straight lines).
TRANSFORMS_1D = ("haar", "alpert2")


@cache
def alpert_matrices(n: int, k: int) -> np.ndarray:
    """Orthogonal ``2k x 2k`` matrices of Alpert's multiwavelet on ``n`` uniform samples.

    Level ``l`` (0 = finest) maps the ``k`` scaling coefficients of two adjacent blocks of
    ``k 2**l`` samples to the ``k`` scaling coefficients of their union (first ``k`` rows:
    the orthonormal projection on polynomials of degree < k) and ``k`` wavelet coefficients
    orthogonal to those polynomials (``k`` vanishing moments). ``k = 1`` is the Haar transform.

    Returns
    -------
    ndarray, shape (log2(n / k), 2k, 2k), read-only.
    """
    mats = []
    child = np.eye(k)  # scaling functions of a block, on its samples
    size = k
    while size < n:
        x = (np.arange(2 * size) - (2 * size - 1) / 2) / size
        parent = np.linalg.qr(np.vander(x, k, increasing=True))[0]
        children = np.zeros((2 * size, 2 * k))
        children[:size, :k] = child
        children[size:, k:] = child
        scaling = children.T @ parent  # (2k, k), orthonormal columns
        wavelets = np.linalg.svd(np.eye(2 * k) - scaling @ scaling.T)[0][:, :k]
        mats.append(np.vstack([scaling.T, wavelets.T]))
        child, size = parent, 2 * size
    out = np.array(mats)
    out.flags.writeable = False
    return out


@njit(cache=True)
def multiwavelet_inplace(v: np.ndarray, tmp: np.ndarray, mats: np.ndarray) -> None:
    """Full 1D multiwavelet transform of ``v`` in place (:func:`alpert_matrices`).

    The result is laid out coarse first: ``[k scaling, k coarsest wavelets, 2k, 4k, ...,
    n/2 finest wavelets]``; the wavelets of scale ``s`` (0 = coarsest) start at ``k 2**s``.
    """
    k = mats.shape[1] // 2
    n = v.shape[0]
    for level in range(mats.shape[0]):
        half = n // 2
        for g in range(half // k):
            for row in range(2 * k):
                acc = 0.0
                for col in range(2 * k):
                    acc += mats[level, row, col] * v[2 * k * g + col]
                tmp[(g * k + row) if row < k else (half + g * k + row - k)] = acc
        v[:n] = tmp[:n]
        n = half


@njit(cache=True)
def _inverse_1d(v: np.ndarray, tmp: np.ndarray, mats: np.ndarray) -> None:
    k = mats.shape[1] // 2
    n = 2 * k
    for level in range(mats.shape[0] - 1, -1, -1):
        half = n // 2
        for g in range(half // k):
            for col in range(2 * k):
                acc = 0.0
                for row in range(2 * k):
                    c = v[g * k + row] if row < k else v[half + g * k + row - k]
                    acc += mats[level, row, col] * c
                tmp[2 * k * g + col] = acc
        v[:n] = tmp[:n]
        n *= 2


@njit(cache=True)
def _rows(x: np.ndarray, mats: np.ndarray, inverse: bool) -> np.ndarray:
    out = x.copy()
    tmp = np.empty(x.shape[1])
    for r in range(x.shape[0]):
        if inverse:
            _inverse_1d(out[r], tmp, mats)
        else:
            multiwavelet_inplace(out[r], tmp, mats)
    return out


def transform_rows(x: np.ndarray, kind: str = "alpert2", inverse: bool = False) -> np.ndarray:
    """:func:`multiwavelet_inplace` (or its inverse) of every row of ``x``, shape (m, n)."""
    k = TRANSFORMS_1D.index(kind) + 1
    return _rows(np.ascontiguousarray(x, dtype=np.float64), alpert_matrices(x.shape[1], k), inverse)


def _square_groups(tree):
    """Yield ``(width, orders, rows, cols)`` for the bandelet squares of each width.

    ``orders`` (n_squares, L*L) is each square's reordering; ``rows`` and ``cols``
    (n_squares, L, L) index the squares' samples in the subband.
    """
    top, left, widths, dirs = tree.leaves()
    for width in np.unique(widths[dirs >= 0]):
        pick = (widths == width) & (dirs >= 0)
        offsets = np.arange(width)
        rows = top[pick, None, None] + offsets[None, :, None]
        cols = left[pick, None, None] + offsets[None, None, :]
        yield int(width), directions(int(width))[1][dirs[pick]], rows, cols


def bandeletize(subband: np.ndarray, tree, kind: str = "alpert2") -> np.ndarray:
    """Bandelet coefficients of one subband for a given quadtree and directions.

    Parameters
    ----------
    subband : ndarray, shape (h, w), float64
        Wavelet coefficients of one subband.
    tree : bandelets.quadtree.Quadtree
        Leaf squares and their directions.
    kind : str
        1D transform, one of :data:`TRANSFORMS_1D`.

    Returns
    -------
    ndarray, shape (h, w): the wavelet coefficients with every square that has a direction
    replaced by its 1D coefficients in zig-zag order.
    """
    out = subband.copy()
    for width, orders, rows, cols in _square_groups(tree):
        squares = subband[rows, cols].reshape(len(rows), -1)
        coeffs = transform_rows(np.take_along_axis(squares, orders, axis=1), kind)
        stored = np.empty_like(coeffs)
        stored[:, zigzag(width)] = coeffs
        out[rows, cols] = stored.reshape(len(rows), width, width)
    return out


def debandeletize(coefficients: np.ndarray, tree, kind: str = "alpert2") -> np.ndarray:
    """Inverse of :func:`bandeletize`: wavelet coefficients of the subband."""
    out = coefficients.copy()
    for _, orders, rows, cols in _square_groups(tree):
        stored = coefficients[rows, cols].reshape(len(rows), -1)
        signal = transform_rows(stored[:, zigzag(rows.shape[1])], kind, inverse=True)
        squares = np.empty_like(signal)
        np.put_along_axis(squares, orders, signal, axis=1)
        out[rows, cols] = squares.reshape(len(rows), rows.shape[1], rows.shape[1])
    return out
