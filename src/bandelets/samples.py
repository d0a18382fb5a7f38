"""Synthetic surfaces the package generates itself, for the demo and the tests.

A CAD-like part seen from above: a height field made of planes, a chamfered square boss,
a round boss with a fillet, a V groove along a curve and a few drilled dimples. Its
normal map has the sharp creases (steps of the normals) that bandelets are built for.
Heights are evaluated analytically and normals by a centred difference far smaller than a
pixel; each pixel averages 4 x 4 such normals (box-filter antialiasing, as a baker renders a
normal map from a CAD model) and is renormalised, so creases are one pixel wide at any size.
"""

from __future__ import annotations

import numpy as np

__all__ = ["crease_height", "crease_normal_map"]


def crease_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height of the synthetic part at points ``(x, y)`` of the unit square."""
    h = 0.08 * x + 0.03 * y  # tilted base plane
    # Chamfered square boss, rotated by 20 degrees: flat top, 45-degree chamfers.
    c, s = np.cos(0.35), np.sin(0.35)
    u, v = c * (x - 0.3) + s * (y - 0.32), -s * (x - 0.3) + c * (y - 0.32)
    inside = 0.16 - np.maximum(np.abs(u), np.abs(v))
    h = h + np.clip(inside, 0.0, 0.05)
    # Round boss with a circular fillet of radius 0.04 at its foot.
    r = np.hypot(x - 0.7, y - 0.68)
    rim = np.clip(0.2 - r, 0.0, None)
    fillet = np.where(rim < 0.04, 0.04 - np.sqrt(np.maximum(0.04**2 - rim**2, 0.0)), rim - 0.04 + 0.04)
    h = h + 0.6 * np.minimum(fillet, 0.07)
    # V groove along a sine curve.
    distance = np.abs(y - (0.82 - 0.08 * np.sin(5.0 * x))) * np.cos(np.arctan(0.4))
    h = h - np.clip(0.02 - 0.5 * distance, 0.0, None)
    # Spherical dimples on a diagonal.
    for k in range(4):
        cx, cy = 0.12 + 0.1 * k, 0.62 + 0.07 * k
        d2 = (x - cx) ** 2 + (y - cy) ** 2
        h = h - np.where(
            d2 < 0.03**2, np.sqrt(np.maximum(0.045**2 - d2, 0.0)) - np.sqrt(0.045**2 - 0.03**2), 0.0
        )
    return h


def crease_normal_map(size: int = 512, supersampling: int = 4) -> np.ndarray:
    """Unit normals of :func:`crease_height`, ``size x size`` pixels, antialiased.

    Parameters
    ----------
    size : int
        Side of the map in pixels.
    supersampling : int
        Normals averaged per pixel side (1: point sampling, aliased creases).

    Returns
    -------
    ndarray, shape (size, size, 3), float64, unit vectors with z > 0.
    """
    fine = size * supersampling
    t = (np.arange(fine) + 0.5) / fine
    y, x = np.meshgrid(t, t, indexing="ij")
    eps = 1e-3 / fine
    dx = (crease_height(x + eps, y) - crease_height(x - eps, y)) / (2 * eps)
    dy = (crease_height(x, y + eps) - crease_height(x, y - eps)) / (2 * eps)
    n = np.stack([-dx, -dy, np.ones_like(dx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n = n.reshape(size, supersampling, size, supersampling, 3).mean(axis=(1, 3))
    return n / np.linalg.norm(n, axis=-1, keepdims=True)
