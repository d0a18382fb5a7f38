"""Steps (4) and (5) of the paper: the directions of an L x L square and their reorderings.

A direction ``d`` reorders the grid points of a square by projecting them orthogonally
onto the line ``d``-perpendicular and sorting the projections. Two directions give the
same order unless a pair of grid points changes side between them, which happens only
at the "critical" angles of the vectors joining two grid points. So the distinct
reorderings are those of one angle strictly inside each interval between consecutive
critical angles: fewer than ``2 L**2`` of them. They are computed once per ``L`` and
cached; the decoder gets the same list in the same order, and the index into it is what
the bitstream stores.

Also here: the zig-zag order in which the 1D coefficients of a square are laid back
into the square (step (9)), coarse first, in the upper-left corner.
"""

from __future__ import annotations

from functools import cache
from math import gcd

import numpy as np

__all__ = ["critical_angles", "directions", "nearest_direction", "zigzag"]


@cache
def critical_angles(width: int) -> np.ndarray:
    """Angles in ``[0, pi)`` of the vectors joining two points of a ``width x width`` grid.

    Returns
    -------
    ndarray, shape (n,), float64, increasing; ``angles[0] == 0``.
    """
    vectors = set()
    for dy in range(width):
        for dx in range(-(width - 1), width):
            if (dy == 0 and dx <= 0) or gcd(abs(dx), dy) != 1:
                continue
            vectors.add((dx, dy))
    return np.sort(np.array([np.arctan2(dy, dx) for dx, dy in vectors]))


@cache
def directions(width: int) -> tuple[np.ndarray, np.ndarray]:
    """The distinct reorderings of a ``width x width`` square.

    Parameters
    ----------
    width : int
        Side ``L`` of the square, in samples.

    Returns
    -------
    angles : ndarray, shape (n_dirs,), float64
        One representative angle (radians, in ``(0, pi)``) per reordering.
    orders : ndarray, shape (n_dirs, L*L), int32
        ``orders[d]`` lists the flat (row-major) indices of the square's samples in the
        order of their projections on the axis orthogonal to direction ``d``: the 1D signal
        ``f_d`` is ``square.ravel()[orders[d]]``. Read-only.
    """
    crit = critical_angles(width)
    mids = (crit + np.append(crit[1:], np.pi)) / 2
    rows, cols = np.divmod(np.arange(width * width), width)
    seen: dict[bytes, int] = {}
    angles, orders = [], []
    for theta in mids:
        # Projection on d-perpendicular = (-sin, cos) in (x = col, y = row) coordinates.
        t = -np.sin(theta) * cols + np.cos(theta) * rows
        order = np.argsort(t, kind="stable").astype(np.int32)
        key = order.tobytes()
        if key not in seen:
            seen[key] = len(orders)
            angles.append(theta)
            orders.append(order)
    out = np.array(orders, dtype=np.int32)
    out.flags.writeable = False
    return np.array(angles), out


@cache
def zigzag(width: int) -> np.ndarray:
    """Flat indices of a ``width x width`` square in JPEG zig-zag order, upper-left first.

    Returns
    -------
    ndarray, shape (L*L,), int64: ``zigzag(L)[k]`` is where the k-th 1D coefficient is stored.
    """
    rows, cols = np.divmod(np.arange(width * width), width)
    diagonal = rows + cols
    # Along odd anti-diagonals go down (by row), along even ones go up (by column).
    along = np.where(diagonal % 2 == 1, rows, cols)
    out = np.lexsort((along, diagonal))
    out.flags.writeable = False
    return out


def nearest_direction(angles: np.ndarray, width: int) -> np.ndarray:
    """Index of the reordering of a ``width x width`` square closest to each angle.

    Parameters
    ----------
    angles : ndarray of float
        Radians; compared cyclically modulo pi.
    width : int

    Returns
    -------
    ndarray of int64, same shape as ``angles``.
    """
    table = directions(width)[0]
    distance = np.abs(np.asarray(angles, float)[..., None] - table)
    return np.argmin(np.minimum(distance, np.pi - distance), axis=-1)
