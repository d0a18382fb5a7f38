"""The octahedral unfolding of the sphere onto the square [-1, 1]^2 (Praun and Hoppe 2003).

The upper hemisphere (z >= 0) fills the diamond ``|u| + |v| <= 1``, one octant per
quadrant; each lower octant is folded out over the diamond's edge into the corner triangle
of its quadrant. Each edge of the square is then glued to itself reversed about its
midpoint, and the four corners are the south pole.

Within an octant the map is the equal-area one: with ``r = sqrt(1 - |z|)`` and
``phi = atan2(|y|, |x|)``, the octant point goes to ``(a, b) = r (1 - t, t)``,
``t = 2 phi / pi``, so equal areas of the sphere fill equal areas of the square (each
octant, of area pi / 2, fills a triangle of area 1/2).
"""

from __future__ import annotations

import numpy as np

__all__ = ["grid", "sphere_to_square", "square_to_sphere"]


def sphere_to_square(points: np.ndarray) -> np.ndarray:
    """Unit vectors to points of the square.

    Parameters
    ----------
    points : ndarray of float, shape (..., 3)
        Unit vectors.

    Returns
    -------
    ndarray of float, shape (..., 2)
        ``(u, v)`` in [-1, 1]^2.
    """
    x, y, z = np.moveaxis(np.asarray(points, dtype=np.float64), -1, 0)
    r = np.sqrt(np.clip(1.0 - np.abs(z), 0.0, 1.0))
    t = np.arctan2(np.abs(y), np.abs(x)) * (2.0 / np.pi)
    a, b = r * (1.0 - t), r * t
    lower = z < 0
    a, b = np.where(lower, 1.0 - b, a), np.where(lower, 1.0 - a, b)
    sx = np.where(x < 0, -1.0, 1.0)
    sy = np.where(y < 0, -1.0, 1.0)
    return np.stack([sx * a, sy * b], axis=-1)


def square_to_sphere(uv: np.ndarray) -> np.ndarray:
    """Points of the square to unit vectors: the inverse of :func:`sphere_to_square`.

    Parameters
    ----------
    uv : ndarray of float, shape (..., 2)
        Points of [-1, 1]^2.

    Returns
    -------
    ndarray of float, shape (..., 3)
        Unit vectors.
    """
    u, v = np.moveaxis(np.asarray(uv, dtype=np.float64), -1, 0)
    a, b = np.abs(u), np.abs(v)
    lower = a + b > 1.0
    a, b = np.where(lower, 1.0 - b, a), np.where(lower, 1.0 - a, b)
    r = a + b
    t = np.divide(b, r, out=np.zeros_like(r), where=r > 0)
    z = 1.0 - r * r
    ring = np.sqrt(np.clip(1.0 - z * z, 0.0, 1.0))
    x = np.where(u < 0, -1.0, 1.0) * ring * np.cos(t * np.pi / 2)
    y = np.where(v < 0, -1.0, 1.0) * ring * np.sin(t * np.pi / 2)
    return np.stack([x, y, np.where(lower, -z, z)], axis=-1)


def grid(size: int) -> np.ndarray:
    """The sample points of an ``size`` x ``size`` geometry image: pixel centres of the square.

    Returns
    -------
    ndarray of float, shape (size, size, 2)
        ``[i, j] = (u_j, v_i)`` with ``u_j = -1 + (2 j + 1) / size``: columns run along u,
        rows along v.
    """
    centres = -1.0 + (2.0 * np.arange(size) + 1.0) / size
    v, u = np.meshgrid(centres, centres, indexing="ij")
    return np.stack([u, v], axis=-1)
