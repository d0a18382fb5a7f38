"""The restoration's penalty, term by term: the log weight of a difference, the scaled differences,
and the terms across the folds of an octahedral image (each border pixel's neighbour across the
fold is the mirrored pixel of the same edge), for :mod:`bandelets.restore.restoration`'s kernels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["across_folds", "log_weight", "scaled", "second_across_folds"]


@njit(cache=True, nogil=True, inline="always")
def log_weight(squared_norm, edge):
    """d(edge log(1 + n / edge))/dn / n, with n = sqrt(squared_norm + 1) (in units of the smoothing)."""
    n = np.sqrt(squared_norm + np.float32(1.0))
    return edge / (n * (edge + n))


@njit(cache=True, nogil=True, inline="always")
def scaled(difference, scale, largest):
    """A difference in units of the smoothing (``scale`` is its inverse), as a float32 of at most
    :data:`_LARGEST`."""
    d = difference * scale
    d = largest if d > largest else d
    d = -largest if d < -largest else d
    return np.float32(d)


@njit(cache=True, nogil=True)
def across_folds(x, i, scale, largest, edge, g):
    """Adds to ``g`` (row ``i`` of the gradient, all channels) the terms of the differences of row
    ``i``'s border pixels with their neighbours across the folds of an octahedral geometry image
    (see :func:`penalty_gradient`): the whole row on the first and last rows, else its ends."""
    rows, cols = x.shape[1:]
    if i == 0 or i == rows - 1:
        for j in range(cols):
            _fold_pair(x, i, j, i, cols - 1 - j, scale, largest, edge, g)
    _fold_pair(x, i, 0, rows - 1 - i, 0, scale, largest, edge, g)
    _fold_pair(x, i, cols - 1, rows - 1 - i, cols - 1, scale, largest, edge, g)


@njit(cache=True, nogil=True)
def second_across_folds(x, i, scale, largest, second_order, second_edge, g):
    """Adds to ``g`` (row ``i`` of the gradient, all channels) the terms of the second differences
    across the folds that reach row ``i`` (see :func:`penalty_gradient`): centred on each border pixel
    ``p``, ``x[f] - 2 x[p] + x[n]``, ``f`` its neighbour across the fold and ``n`` the one inside."""
    rows, cols = x.shape[1:]
    constants = (scale, largest, second_order, second_edge)
    for edge, inside in ((0, 1), (rows - 1, rows - 2)):  # the first and last rows
        if i == edge:
            for j in range(cols):
                m = cols - 1 - j
                _second_term(x, (edge, j), (edge, m), (inside, j), -2.0, j, constants, g)
                _second_term(x, (edge, m), (edge, j), (inside, m), 1.0, j, constants, g)
        elif i == inside:
            for j in range(cols):
                _second_term(x, (edge, j), (edge, cols - 1 - j), (inside, j), 1.0, j, constants, g)
    m = rows - 1 - i
    for edge, inside in ((0, 1), (cols - 1, cols - 2)):  # the first and last columns
        _second_term(x, (i, edge), (m, edge), (i, inside), -2.0, edge, constants, g)
        _second_term(x, (m, edge), (i, edge), (m, inside), 1.0, edge, constants, g)
        _second_term(x, (i, edge), (m, edge), (i, inside), 1.0, inside, constants, g)


@njit(cache=True, nogil=True, inline="always")
def _second_term(x, p, f, n, coefficient, j, constants, g):
    """``g[:, j] += coefficient w D``, ``D = x[:, f] - 2 x[:, p] + x[:, n]`` (pixels ``(row, column)``)
    and ``w`` ``second_order`` times the weight of that joint second difference (``constants``:
    ``scale, largest, second_order, second_edge``, see :func:`_rows`)."""
    scale, largest, second_order, second_edge = constants
    s = np.float32(0.0)
    for c in range(x.shape[0]):
        e = scaled(x[c, f[0], f[1]] - 2.0 * x[c, p[0], p[1]] + x[c, n[0], n[1]], scale, largest)
        s += e * e
    w = second_order * log_weight(s, second_edge) * np.float32(coefficient)
    for c in range(x.shape[0]):
        g[c, j] += scaled(x[c, f[0], f[1]] - 2.0 * x[c, p[0], p[1]] + x[c, n[0], n[1]], scale, largest) * w


@njit(cache=True, nogil=True, inline="always")
def _fold_pair(x, i, j, m, n, scale, largest, edge, g):
    """``g[:, j] += w (x[:, i, j] - x[:, m, n])``, ``w`` the weight of that joint difference."""
    s = np.float32(0.0)
    for c in range(x.shape[0]):
        e = scaled(x[c, i, j] - x[c, m, n], scale, largest)
        s += e * e
    w = log_weight(s, edge)
    for c in range(x.shape[0]):
        g[c, j] += scaled(x[c, i, j] - x[c, m, n], scale, largest) * w
