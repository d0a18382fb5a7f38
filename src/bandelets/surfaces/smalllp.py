"""Small dense linear programs, solved in compiled code without per-call overhead.

``maximise c . x subject to A x <= b`` over free variables ``x``, by the two-phase simplex
method on a dense tableau with Bland's rule (which cannot cycle). Meant for a few variables and a
few dozen constraints: the untangling of a spherical parameterization (:mod:`.sphere`) solves one
3-variable program per moved vertex, tens of thousands per mesh.

Written here because no library solves many tiny linear programs cheaply: scipy's ``linprog``
(HiGHS) spends about 5 ms per call on its set-up whatever the size (fandisk's untangling made
35,970 calls: 160 s), and cannot be called from numba; this one takes microseconds.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["OPTIMAL", "INFEASIBLE", "UNBOUNDED", "NUMERICAL", "maximize"]

# The status codes of scipy.optimize.linprog.
OPTIMAL, INFEASIBLE, UNBOUNDED, NUMERICAL = 0, 2, 3, 4


@njit(cache=True)
def _pivot(tableau, basis, row, col):
    tableau[row, :] /= tableau[row, col]
    for i in range(tableau.shape[0]):
        factor = tableau[i, col]
        if i != row and factor != 0.0:
            tableau[i, :] -= factor * tableau[row, :]
    basis[row] = col


@njit(cache=True)
def _simplex(tableau, basis, columns, tol):
    """Pivot until the last row (reduced costs of a minimisation, the objective's opposite in its
    last entry) has no entry below ``-tol`` among the first ``columns``. Returns a status."""
    m = tableau.shape[0] - 1
    rhs = tableau.shape[1] - 1
    for _ in range(50 * (m + columns)):
        col = -1
        for j in range(columns):  # Bland: the first improving column
            if tableau[m, j] < -tol:
                col = j
                break
        if col < 0:
            return OPTIMAL
        row = -1
        best = np.inf
        for i in range(m):
            if tableau[i, col] > tol:
                ratio = tableau[i, rhs] / tableau[i, col]
                # Bland: among equal ratios, the row whose basic variable comes first.
                if ratio < best or (ratio == best and basis[i] < basis[row]):
                    row, best = i, ratio
        if row < 0:
            return UNBOUNDED
        _pivot(tableau, basis, row, col)
    return NUMERICAL


@njit(cache=True)
def maximize(c, a, b, tol=1e-9):
    """Maximise ``c . x`` subject to ``a @ x <= b``, ``x`` free.

    Parameters
    ----------
    c : ndarray of float, shape (n,)
    a : ndarray of float, shape (m, n)
        Coefficients of order 1 (``tol`` is absolute).
    b : ndarray of float, shape (m,)
    tol : float
        Tolerance of the pivots, reduced costs and feasibility.

    Returns
    -------
    status : int
        ``OPTIMAL`` (0), ``INFEASIBLE`` (2), ``UNBOUNDED`` (3) or ``NUMERICAL`` (4, an iteration
        cap that Bland's rule should never reach), as scipy's ``linprog``.
    x : ndarray of float, shape (n,)
        An optimal point (zeros unless ``OPTIMAL``).
    value : float
        ``c . x`` (NaN unless ``OPTIMAL``).
    """
    m, n = a.shape
    negative = 0
    for i in range(m):
        if b[i] < 0:
            negative += 1
    # Columns: x = p - q (p, q >= 0), a slack per row, an artificial per row with b < 0.
    real = 2 * n + m
    tableau = np.zeros((m + 1, real + negative + 1))
    basis = np.empty(m, dtype=np.int64)
    art = real
    for i in range(m):
        sign = -1.0 if b[i] < 0 else 1.0
        for j in range(n):
            tableau[i, j] = sign * a[i, j]
            tableau[i, n + j] = -sign * a[i, j]
        tableau[i, 2 * n + i] = sign
        tableau[i, -1] = sign * b[i]
        if sign < 0:
            tableau[i, art] = 1.0
            basis[i] = art
            art += 1
        else:
            basis[i] = 2 * n + i
    x = np.zeros(n)
    if negative:
        # Phase 1: minimise the sum of the artificials.
        for i in range(m):
            if basis[i] >= real:
                tableau[m, :real] -= tableau[i, :real]
                tableau[m, -1] -= tableau[i, -1]
        status = _simplex(tableau, basis, real + negative, tol)
        if status != OPTIMAL:
            return status, x, np.nan
        if -tableau[m, -1] > tol * (1.0 + np.max(np.abs(b))):
            return INFEASIBLE, x, np.nan
        for i in range(m):  # artificials left in the basis at zero: swap them out if a row allows
            if basis[i] >= real:
                for j in range(real):
                    if abs(tableau[i, j]) > tol:
                        _pivot(tableau, basis, i, j)
                        break
    # Phase 2: minimise -c . x over the real columns.
    cost = np.zeros(real + negative)
    cost[:n] = -c
    cost[n : 2 * n] = c
    tableau[m, :-1] = cost
    tableau[m, -1] = 0.0
    for i in range(m):
        if cost[basis[i]] != 0.0:
            tableau[m, :] -= cost[basis[i]] * tableau[i, :]
    status = _simplex(tableau, basis, real, tol)
    if status != OPTIMAL:
        return status, x, np.nan
    for i in range(m):
        if basis[i] < n:
            x[basis[i]] += tableau[i, -1]
        elif basis[i] < 2 * n:
            x[basis[i] - n] -= tableau[i, -1]
    return OPTIMAL, x, float(c @ x)
