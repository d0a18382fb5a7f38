"""Steps (5) to (7) and (9) of the paper: bandeletization of one wavelet subband.

Inside every leaf square of the quadtree that has a direction ``d``, the wavelet
coefficients are read in the order of ``d`` (:func:`bandelets.transform.geometry.directions`),
transformed by a full orthonormal 1D wavelet transform (coarse first: approximation,
then the coarsest detail, ..., the finest details): Haar, as in the paper, or Alpert's
multiwavelet with two vanishing moments, the paper's choice for its theorem, which also
cancels the linear part of a blurred crease profile, and written back into the square in zig-zag
order. Squares without a direction (``d = NULL``, stored as -1) keep their wavelet
coefficients. Both steps are permutations and orthonormal maps, so the whole is an
orthonormal change of basis of the subband, inverted exactly by :func:`debandeletize`.

A compiled loop reads, transforms and writes back the squares of one width one by one,
straight from and into the subband: no index arrays.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from numba import njit

from ..format.fields import DEFAULT_TRANSFORM_1D
from ..format.quantizer import MAX_INDEX, RECONSTRUCTION
from .geometry import directions, zigzag

__all__ = [
    "ORDER",
    "alpert_matrices",
    "multiwavelet",
    "transform_rows",
    "bandeletize",
    "debandeletize",
    "debandeletize_bins",
]

#: The order ``k`` of the polynomial reproduction of each 1D transform along the reordered samples
#: (:data:`bandelets.format.header.TRANSFORMS_1D`): Haar (constants) and Alpert's multiwavelet with
#: ``k = 2`` (straight lines).
ORDER = {"haar": 1, "alpert2": 2}


def _dot(a, b) -> float:
    """Correctly rounded dot product: the same bits on every CPU (BLAS and LAPACK are not)."""
    return math.fsum(x * y for x, y in zip(a, b, strict=True))


def _orthonormalise(vectors: list[list[float]], against: list[list[float]]) -> list[list[float]]:
    """Gram-Schmidt of ``vectors``, in order, against ``against`` and each other (twice, for accuracy)."""
    basis = list(against)
    for v in vectors:
        for _ in range(2):
            for b in basis:
                c = _dot(v, b)
                v = [x - c * y for x, y in zip(v, b, strict=True)]
        norm = math.sqrt(_dot(v, v))
        basis.append([x / norm for x in v])
    return basis[len(against) :]


def _in_children(f: list[float], child: list[list[float]]) -> list[float]:
    """Coefficients of ``f``, a function on two adjacent blocks, in the blocks' scaling functions."""
    size = len(child[0])
    return [_dot(c, f[:size]) for c in child] + [_dot(c, f[size:]) for c in child]


@cache
def alpert_matrices(n: int, k: int) -> np.ndarray:
    """Orthogonal ``2k x 2k`` matrices of Alpert's multiwavelet on ``n`` uniform samples.

    Level ``l`` (0 = finest) maps the ``k`` scaling coefficients of two adjacent blocks of
    ``k 2**l`` samples to the ``k`` scaling coefficients of their union (first ``k`` rows:
    the orthonormal projection on polynomials of degree < k) and ``k`` wavelet coefficients
    orthogonal to those polynomials (``k`` vanishing moments). ``k = 1`` is the Haar transform.

    The wavelets are the functions ``sign(x) x**j`` (``j < k``, ``x`` centred on the union)
    made orthogonal to the polynomials and to each other, in that order: any orthonormal
    basis of that space has the vanishing moments, but the file format needs one that every
    machine computes to the same bits, so the basis is fixed by construction and computed
    with correctly rounded sums (an SVD or QR through LAPACK returned another rotation on
    another CPU, and files decoded differently there).

    Returns
    -------
    ndarray, shape (log2(n / k), 2k, 2k), read-only.

    Examples
    --------
    >>> m = alpert_matrices(8, 2)
    >>> m.shape
    (2, 4, 4)
    >>> bool(np.allclose(m[0] @ m[0].T, np.eye(4)))
    True
    """
    mats = []
    child = [[float(i == j) for j in range(k)] for i in range(k)]  # k functions on k samples
    size = k
    while size < n:
        x = [(i - (2 * size - 1) / 2) / size for i in range(2 * size)]
        monomials = [[1.0] * (2 * size)]
        for _ in range(1, k):  # products, not pow: the same bits everywhere
            monomials.append([m * xi for m, xi in zip(monomials[-1], x, strict=True)])
        parent = _orthonormalise(monomials, [])
        scaling = [_in_children(p, child) for p in parent]
        steps = [[m if xi > 0 else -m for xi, m in zip(x, mono, strict=True)] for mono in monomials]
        wavelets = _orthonormalise([_in_children(s, child) for s in steps], scaling)
        mats.append(scaling + wavelets)
        child, size = parent, 2 * size
    out = np.array(mats, dtype=np.float64).reshape(-1, 2 * k, 2 * k)
    out.flags.writeable = False
    return out


@njit(cache=True, nogil=True, inline="always")
def _forward_level(src, scaling, wavelets, mats, level, n, k):
    """One level of the transform of ``src[:n]``: for every group of ``2k`` samples, the first ``k``
    rows of the level's matrix give scaling coefficients (into ``scaling[:n/2]``), the last ``k``
    wavelet coefficients (into ``wavelets[n/2:n]``), each product summed over the columns in
    order from 0.0."""
    half = n // 2
    if k == 2:  # the matrix held in registers: 2.3x faster at 4 x 4, the same arithmetic
        m = mats[level]
        m00, m01, m02, m03 = m[0, 0], m[0, 1], m[0, 2], m[0, 3]
        m10, m11, m12, m13 = m[1, 0], m[1, 1], m[1, 2], m[1, 3]
        m20, m21, m22, m23 = m[2, 0], m[2, 1], m[2, 2], m[2, 3]
        m30, m31, m32, m33 = m[3, 0], m[3, 1], m[3, 2], m[3, 3]
        for g in range(half // 2):
            x0, x1, x2, x3 = src[4 * g], src[4 * g + 1], src[4 * g + 2], src[4 * g + 3]
            scaling[2 * g] = 0.0 + m00 * x0 + m01 * x1 + m02 * x2 + m03 * x3
            scaling[2 * g + 1] = 0.0 + m10 * x0 + m11 * x1 + m12 * x2 + m13 * x3
            wavelets[half + 2 * g] = 0.0 + m20 * x0 + m21 * x1 + m22 * x2 + m23 * x3
            wavelets[half + 2 * g + 1] = 0.0 + m30 * x0 + m31 * x1 + m32 * x2 + m33 * x3
    elif k == 1:
        m00, m01, m10, m11 = mats[level, 0, 0], mats[level, 0, 1], mats[level, 1, 0], mats[level, 1, 1]
        for g in range(half):
            x0, x1 = src[2 * g], src[2 * g + 1]
            scaling[g] = 0.0 + m00 * x0 + m01 * x1
            wavelets[half + g] = 0.0 + m10 * x0 + m11 * x1
    else:
        for g in range(half // k):
            for row in range(2 * k):
                acc = 0.0
                for col in range(2 * k):
                    acc += mats[level, row, col] * src[2 * k * g + col]
                if row < k:
                    scaling[g * k + row] = acc
                else:
                    wavelets[half + g * k + row - k] = acc


@njit(cache=True, nogil=True, inline="always")
def _forward(v, tmp, out, mats, k):
    n = v.shape[0]
    src, dst = v, tmp
    for level in range(mats.shape[0]):
        _forward_level(src, dst, out, mats, level, n, k)
        src, dst = dst, src
        n //= 2
    for i in range(k):
        out[i] = src[i]


@njit(cache=True, nogil=True)
def multiwavelet(v: np.ndarray, tmp: np.ndarray, out: np.ndarray, mats: np.ndarray) -> None:
    """Full 1D multiwavelet transform of ``v`` into ``out`` (:func:`alpert_matrices`).

    The result is laid out coarse first: ``[k scaling, k coarsest wavelets, 2k, 4k, ...,
    n/2 finest wavelets]``; the wavelets of scale ``s`` (0 = coarsest) start at ``k 2**s``.
    ``v`` and ``tmp`` (same length) are overwritten: the scaling coefficients of each level go
    back and forth between them, the wavelets straight to their place in ``out``.
    """
    # One loop per literal order: the compiler unrolls the small matrix products (the same
    # arithmetic); a choice of the order inside the loop ran 3x slower at 4 x 4.
    k = mats.shape[1] // 2
    if k == 2:
        _forward(v, tmp, out, mats, 2)
    elif k == 1:
        _forward(v, tmp, out, mats, 1)
    else:
        _forward(v, tmp, out, mats, k)


@njit(cache=True, nogil=True, inline="always")
def _inverse_level(scaling, wavelets, dst, mats, level, n, k):
    """Inverse of :func:`_forward_level`: ``dst[:n]`` from ``scaling[:n/2]`` and
    ``wavelets[n/2:n]``, each sample summed over the rows in order from 0.0."""
    half = n // 2
    if k == 2:
        m = mats[level]
        m00, m01, m02, m03 = m[0, 0], m[0, 1], m[0, 2], m[0, 3]
        m10, m11, m12, m13 = m[1, 0], m[1, 1], m[1, 2], m[1, 3]
        m20, m21, m22, m23 = m[2, 0], m[2, 1], m[2, 2], m[2, 3]
        m30, m31, m32, m33 = m[3, 0], m[3, 1], m[3, 2], m[3, 3]
        for g in range(half // 2):
            s0, s1 = scaling[2 * g], scaling[2 * g + 1]
            w0, w1 = wavelets[half + 2 * g], wavelets[half + 2 * g + 1]
            dst[4 * g] = 0.0 + m00 * s0 + m10 * s1 + m20 * w0 + m30 * w1
            dst[4 * g + 1] = 0.0 + m01 * s0 + m11 * s1 + m21 * w0 + m31 * w1
            dst[4 * g + 2] = 0.0 + m02 * s0 + m12 * s1 + m22 * w0 + m32 * w1
            dst[4 * g + 3] = 0.0 + m03 * s0 + m13 * s1 + m23 * w0 + m33 * w1
    elif k == 1:
        m00, m01, m10, m11 = mats[level, 0, 0], mats[level, 0, 1], mats[level, 1, 0], mats[level, 1, 1]
        for g in range(half):
            s0, w0 = scaling[g], wavelets[half + g]
            dst[2 * g] = 0.0 + m00 * s0 + m10 * w0
            dst[2 * g + 1] = 0.0 + m01 * s0 + m11 * w0
    else:
        for g in range(half // k):
            for col in range(2 * k):
                acc = 0.0
                for row in range(2 * k):
                    c = scaling[g * k + row] if row < k else wavelets[half + g * k + row - k]
                    acc += mats[level, row, col] * c
                dst[2 * k * g + col] = acc


@njit(cache=True, nogil=True, inline="always")
def _inverse(v, tmp, out, mats, k):
    levels = mats.shape[0]
    if levels == 0:
        for i in range(v.shape[0]):
            out[i] = v[i]
    # The finest level (0) writes out; the coarser ones alternate so that each reads the other.
    src, dst, other = v, out, tmp
    if levels % 2 == 0:
        dst, other = tmp, out
    n = 2 * k
    for level in range(levels - 1, -1, -1):
        _inverse_level(src, v, dst, mats, level, n, k)
        src, dst, other = dst, other, dst
        n *= 2


@njit(cache=True, nogil=True)
def _inverse_multiwavelet(v: np.ndarray, tmp: np.ndarray, out: np.ndarray, mats: np.ndarray) -> None:
    """Inverse of :func:`multiwavelet`: the samples of the coefficients ``v`` into ``out``
    (``v`` is read only; ``tmp`` and ``out`` hold the scaling coefficients of each level)."""
    k = mats.shape[1] // 2
    if k == 2:
        _inverse(v, tmp, out, mats, 2)
    elif k == 1:
        _inverse(v, tmp, out, mats, 1)
    else:
        _inverse(v, tmp, out, mats, k)


@njit(cache=True, nogil=True)
def _rows(x: np.ndarray, mats: np.ndarray, inverse: bool) -> np.ndarray:
    out = np.empty_like(x)
    v = np.empty(x.shape[1])
    tmp = np.empty(x.shape[1])
    for r in range(x.shape[0]):
        v[:] = x[r]
        if inverse:
            _inverse_multiwavelet(v, tmp, out[r], mats)
        else:
            multiwavelet(v, tmp, out[r], mats)
    return out


def transform_rows(x: np.ndarray, kind: str = DEFAULT_TRANSFORM_1D, inverse: bool = False) -> np.ndarray:
    """:func:`multiwavelet` (or its inverse) of every row of ``x``, shape (m, n)."""
    k = ORDER[kind]
    return _rows(np.ascontiguousarray(x, dtype=np.float64), alpert_matrices(x.shape[1], k), inverse)


def _square_groups(tree):
    """Yield ``(width, orders, top, left, dirs)`` for the bandelet squares of each width.

    ``orders`` (n_dirs, L*L) holds the reorderings of that width; ``top``, ``left`` and
    ``dirs`` (n_squares,) the corner and direction index of each of its squares.
    """
    for width, top, left, dirs in tree.squares:
        yield width, directions(width)[1], top, left, dirs


@njit(cache=True, nogil=True)
def _squares(source, out, width, top, left, dirs, orders, stored, mats, inverse):
    """(Inverse) bandeletization of the squares of one width, read from ``source`` and written
    into ``out``: samples in the direction's order, 1D transform, zig-zag storage ``stored``."""
    n = width * width
    v = np.empty(n)
    tmp = np.empty(n)
    w = np.empty(n)
    for s in range(top.shape[0]):
        order = orders[dirs[s]]
        if inverse:
            for i in range(n):
                v[i] = source[top[s] + stored[i] // width, left[s] + stored[i] % width]
            _inverse_multiwavelet(v, tmp, w, mats)
            for i in range(n):
                out[top[s] + order[i] // width, left[s] + order[i] % width] = w[i]
        else:
            for i in range(n):
                v[i] = source[top[s] + order[i] // width, left[s] + order[i] % width]
            multiwavelet(v, tmp, w, mats)
            for i in range(n):
                out[top[s] + stored[i] // width, left[s] + stored[i] % width] = w[i]


def _transform(subband: np.ndarray, tree, kind: str, inverse: bool, out: np.ndarray | None) -> np.ndarray:
    subband = np.asarray(subband, dtype=np.float64)
    if out is None:
        out = subband.copy()
    elif out is not subband:
        out[...] = subband
    # Each square is read whole before it is written: in place is safe.
    k = ORDER[kind]
    for width, orders, top, left, dirs in _square_groups(tree):
        mats = alpert_matrices(width * width, k)
        _squares(subband, out, width, top, left, dirs, orders, zigzag(width), mats, inverse)
    return out


def bandeletize(
    subband: np.ndarray, tree, kind: str = DEFAULT_TRANSFORM_1D, out: np.ndarray | None = None
) -> np.ndarray:
    """Bandelet coefficients of one subband for a given quadtree and directions.

    Parameters
    ----------
    subband : ndarray, shape (h, w), float64
        Wavelet coefficients of one subband.
    tree : bandelets.transform.quadtree.Quadtree
        Leaf squares and their directions.
    kind : str
        1D transform, one of :data:`bandelets.format.header.TRANSFORMS_1D`.
    out : ndarray, shape (h, w), float64, optional
        Where to write the result (``subband`` itself for a transform in place).

    Returns
    -------
    ndarray, shape (h, w): the wavelet coefficients with every square that has a direction
    replaced by its 1D coefficients in zig-zag order.
    """
    return _transform(subband, tree, kind, False, out)


def debandeletize(
    coefficients: np.ndarray, tree, kind: str = DEFAULT_TRANSFORM_1D, out: np.ndarray | None = None
) -> np.ndarray:
    """Inverse of :func:`bandeletize`: wavelet coefficients of the subband (into ``out`` if given)."""
    return _transform(coefficients, tree, kind, True, out)


@njit(cache=True, nogil=True)
def _bins(bins, width, top, left, dirs, orders, stored, mats, threshold):
    n = width * width
    v = np.empty(n)
    tmp = np.empty(n)
    w = np.empty(n)
    for s in range(top.shape[0]):
        order = orders[dirs[s]]
        for i in range(n):
            q = bins[top[s] + stored[i] // width, left[s] + stored[i] % width]
            # quantize.dequantize, one value at a time.
            x = (abs(q) + RECONSTRUCTION) * threshold
            v[i] = x if q > 0 else (-x if q < 0 else 0.0)
        _inverse_multiwavelet(v, tmp, w, mats)
        for i in range(n):
            b = w[i] / threshold
            # Hostile thresholds can overflow: the bins must stay small integers.
            if b != b:
                b = 0.0
            b = min(max(b, -MAX_INDEX), MAX_INDEX)
            bins[top[s] + order[i] // width, left[s] + order[i] % width] = int(b)


def debandeletize_bins(bins: np.ndarray, tree, threshold: float, kind: str = DEFAULT_TRANSFORM_1D) -> None:
    """Replace, in place, the bin indices of every bandelet square by those of the wavelet
    coefficients they decode to: ``fix(debandeletize(dequantize(bins)) / T)``, clipped to
    ``[-MAX_INDEX, MAX_INDEX]`` (NaN gives 0).

    Parameters
    ----------
    bins : ndarray of int64, shape (h, w)
        Signed bin indices of one subband (a view may be passed); outside the squares untouched.
    tree : bandelets.transform.quadtree.Quadtree
    threshold : float
        ``T``.
    kind : str
        1D transform, one of :data:`bandelets.format.header.TRANSFORMS_1D`.
    """
    k = ORDER[kind]
    for width, orders, top, left, dirs in _square_groups(tree):
        mats = alpert_matrices(width * width, k)
        _bins(bins, width, top, left, dirs, orders, zigzag(width), mats, float(threshold))
