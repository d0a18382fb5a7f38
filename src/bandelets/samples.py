"""Synthetic surfaces the package generates itself, for the demo and the tests.

The bevel map (:func:`bevel_normal_map`) is of another kind: what a normal-map tool makes of a
drawing (lettering and a few shapes raised over a flat background by a bevel, a fine bumpy
texture on their faces), stored as an 8-bit PNG is, its background exactly ``(128, 128, 255)``.

A CAD-like part seen from above: a height field made of planes, a chamfered square boss,
a round boss with a fillet, a V groove along a curve and a few drilled dimples. Its
normal map has the sharp creases (steps of the normals) that bandelets are built for.
Heights are evaluated analytically and normals by a centred difference far smaller than a
pixel; each pixel averages 4 x 4 such normals (box-filter antialiasing, as a baker renders a
normal map from a CAD model) and is renormalised, so creases are one pixel wide at any size.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "bevel_normal_map",
    "blurred_edge",
    "bump_height",
    "bump_normal_map",
    "crease_height",
    "crease_normal_map",
    "normal_map",
]


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
    return normal_map(crease_height, size, supersampling)


def normal_map(height, size: int = 512, supersampling: int = 4) -> np.ndarray:
    """Unit normals of any height field, ``size x size`` pixels, antialiased.

    Parameters
    ----------
    height : callable
        ``height(x, y)`` on arrays of points of the unit square (``x`` = column, ``y`` = row).
    size : int
        Side of the map in pixels.
    supersampling : int
        Normals averaged per pixel side (1: point sampling).

    Returns
    -------
    ndarray, shape (size, size, 3), float64, unit vectors with z > 0.
    """
    x, y = _fine_grid(size, supersampling)
    eps = 1e-3 / (size * supersampling)
    dx = (height(x + eps, y) - height(x - eps, y)) / (2 * eps)
    dy = (height(x, y + eps) - height(x, y - eps)) / (2 * eps)
    n = np.stack([-dx, -dy, np.ones_like(dx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n = _box(n, size, supersampling)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _fine_grid(size: int, supersampling: int) -> tuple[np.ndarray, np.ndarray]:
    """``x, y`` at the centres of a ``size * supersampling`` grid on the unit square."""
    t = (np.arange(size * supersampling) + 0.5) / (size * supersampling)
    y, x = np.meshgrid(t, t, indexing="ij")
    return x, y


def _box(fine: np.ndarray, size: int, supersampling: int) -> np.ndarray:
    """Mean of every ``supersampling x supersampling`` block: a pixel's box filter."""
    shape = (size, supersampling, size, supersampling) + fine.shape[2:]
    return fine.reshape(shape).mean(axis=(1, 3))


def bump_height(x: np.ndarray, y: np.ndarray, seed: int = 0) -> np.ndarray:
    """A height field of a hundred smooth Gaussian bumps and dents (seeded) on a gentle slope.

    Radii range from 1 % to 4 % of the side and slopes reach about 1, so that the normal
    map costs about as many bits as the crease map (35 to 65 dB at 0.25 to 2 bpp, 256 x 256).
    """
    rng = np.random.default_rng(seed)
    h = 0.05 * x - 0.02 * y
    for cx, cy, radius, amplitude in zip(
        rng.uniform(0.05, 0.95, 100),
        rng.uniform(0.05, 0.95, 100),
        rng.uniform(0.01, 0.04, 100),
        rng.uniform(-1.0, 1.0, 100),
        strict=True,
    ):
        h = h + amplitude * radius * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * radius**2))
    return h


def bump_normal_map(size: int = 512, seed: int = 0) -> np.ndarray:
    """Normal map of :func:`bump_height`: smooth everywhere, the weak case for bandelets.

    Each pixel averages 2 x 2 normals: nothing is sharp enough to need more.

    Returns
    -------
    ndarray, shape (size, size, 3), float64, unit vectors with z > 0.
    """
    return normal_map(lambda x, y: bump_height(x, y, seed), size, supersampling=2)


def blurred_edge(
    size: int = 512, profile: str = "step", seed: int = 0, blur: float = 0.03, supersampling: int = 4
) -> np.ndarray:
    """The paper's functional model (figure 1 (a)): a C^2 image with a C^2 curved edge,
    blurred by a kernel whose width grows along the edge.

    ``f = g + a * (e * h_s)`` where ``g`` is a smooth background (a few random low-frequency
    cosines), the edge is the graph of a C^2 curve ``y = c(x)``, ``e`` is the Heaviside step
    (``profile="step"``, the normal-map case) or the ramp ``max(d, 0)`` (``profile="tangent"``,
    a tangent discontinuity, the geometry-image case) of the signed distance ``d`` to the
    curve, and ``h_s`` a smooth bell-shaped kernel (the logistic density of scale ``s``)
    whose width grows linearly from 0 (a sharp edge) at the left border to ``blur`` times
    the side at the right border. The blur is evaluated across the edge in closed form (the logistic
    ``1 / (1 + exp(-d / s))`` for the step, ``s log(1 + exp(d / s))`` for the ramp), exact
    for a straight edge and a close approximation for a gently curved one; each pixel
    averages ``supersampling**2`` samples.

    Parameters
    ----------
    size : int
        Side of the image in pixels.
    profile : {"step", "tangent"}
    seed : int
        Seeds the background, the curve's phase and amplitude.
    blur : float
        Width of the kernel at the right border, as a fraction of the side (0: sharp).
    supersampling : int

    Returns
    -------
    ndarray, shape (size, size), float64, values in about [0, 1].
    """
    if profile not in ("step", "tangent"):
        raise ValueError(f"profile must be 'step' or 'tangent', got {profile!r}")
    rng = np.random.default_rng(seed)
    x, y = _fine_grid(size, supersampling)
    phase, bend = rng.uniform(0, 2 * np.pi), rng.uniform(0.08, 0.14)
    curve = 0.5 + bend * np.sin(2.0 * np.pi * x + phase)
    slope = 2.0 * np.pi * bend * np.cos(2.0 * np.pi * x + phase)
    d = (y - curve) / np.sqrt(1.0 + slope**2)
    s = np.maximum(blur * x, 1e-9)
    if profile == "step":
        edge = 0.35 / (1.0 + np.exp(-np.clip(d / s, -700, 700)))
    else:
        edge = s * np.logaddexp(0.0, d / s)
    background = 0.3 + sum(
        0.05 * np.cos(2 * np.pi * (fx * x + fy * y) + p)
        for fx, fy, p in zip(
            rng.uniform(-1.5, 1.5, 4), rng.uniform(-1.5, 1.5, 4), rng.uniform(0, 2 * np.pi, 4), strict=True
        )
    )
    return _box(background + edge, size, supersampling)


def bevel_normal_map(
    size: int = 512, bevel: float = 0.02, texture: float = 0.0002, seed: int = 0, supersampling: int = 2
) -> np.ndarray:
    """A tangent-space normal map of bevelled lettering and shapes, 8-bit RGB samples.

    Two words and five shapes (a disc with a ring cut out of it, a triangle, a hexagon, a tilted
    bar) drawn by matplotlib (DejaVu Sans Bold, no antialiasing) on a grid ``supersampling`` times
    finer than the map are raised over a flat background: the height is the distance to the
    drawing's edge clipped at ``bevel`` (a 45-degree chamfer around the letters, the triangle and
    the bar; a rounded profile, ``bevel (1 - (1 - d / bevel)**2)``, around the disc and the
    hexagon), plus on the faces a fine bumpy texture (Gaussian noise smoothed over 1.2 pixels,
    standard deviation ``texture``, fading in over the bevel). Normals come from the height's
    centred differences, each pixel averages ``supersampling**2`` of them (renormalised), and
    they are rounded to 8 bits as a PNG holds them (:func:`bandelets.io.files.to_samples`): the
    background, about 64 % of the pixels, is exactly ``(128, 128, 255)``. Lengths are fractions
    of the side, so the map looks the same at every size. About 0.5 s at 512 (the first call
    also imports matplotlib).

    Parameters
    ----------
    size : int
        Side of the map in pixels (at least 16).
    bevel : float
        Width (and height) of the bevel, as a fraction of the side.
    texture : float
        Standard deviation of the texture's height, as a fraction of the side (0: smooth faces).
    seed : int
        Seeds the texture.
    supersampling : int
        Heights per pixel side.

    Returns
    -------
    ndarray, shape (size, size, 3), uint8
        ``(n + 1) / 2 * 255`` rounded, as a PNG normal map stores the unit normals ``n``
        (:func:`bandelets.io.files.from_samples` gives them back).
    """
    from scipy import ndimage

    from .format.samples import to_samples

    if size < 16:
        raise ValueError(f"the size must be at least 16, got {size}")
    side = size * supersampling
    chamfered, rounded = _drawing(side)
    t = np.minimum(ndimage.distance_transform_edt(chamfered | rounded) / (side * bevel), 1.0)
    height = bevel * np.where(rounded, 1.0 - (1.0 - t) ** 2, t)
    if texture > 0:
        noise = ndimage.gaussian_filter(
            np.random.default_rng(seed).standard_normal((side, side)), 1.2 * supersampling
        )
        height += texture / noise.std() * noise * t
    dy, dx = np.gradient(height, 1.0 / side)
    n = np.stack([-dx, -dy, np.ones_like(dx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n = _box(n, size, supersampling)
    return to_samples(n / np.linalg.norm(n, axis=-1, keepdims=True), "normal-map", 8)


def _drawing(side: int) -> tuple[np.ndarray, np.ndarray]:
    """The bevel map's drawing, ``side x side`` pixels: masks of the shapes with a chamfer and of
    those with a rounded bevel (disjoint), matplotlib's Agg renderer without antialiasing."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.font_manager import FontProperties
    from matplotlib.patches import Circle, PathPatch, Polygon, Rectangle, RegularPolygon, Wedge
    from matplotlib.textpath import TextPath
    from matplotlib.transforms import Affine2D

    figure = Figure(figsize=(side / 100, side / 100), dpi=100)
    axes = figure.add_axes((0, 0, 1, 1))
    axes.set_xlim(0, 1)
    axes.set_ylim(1, 0)  # y down, as the rows of the map
    axes.axis("off")
    chamfer, round_, cut = ({"facecolor": c, "edgecolor": "none", "antialiased": False} for c in "rbw")
    font = FontProperties(family="DejaVu Sans", weight="bold")
    for word, (x0, baseline, width) in (("Bevel", (0.05, 0.33, 0.9)), ("Normal 42", (0.05, 0.53, 0.9))):
        path = TextPath((0, 0), word, size=1.0, prop=font)
        box = path.get_extents()
        scale = width / box.width
        place = Affine2D().translate(-box.x0, -box.y0).scale(scale, -scale).translate(x0, baseline)
        axes.add_patch(PathPatch(place.transform_path(path), **chamfer))
    axes.add_patch(Circle((0.17, 0.78), 0.16, **round_))
    axes.add_patch(Wedge((0.17, 0.78), 0.1, 0, 360, width=0.035, **cut))
    axes.add_patch(Polygon([(0.35, 0.96), (0.48, 0.6), (0.62, 0.95)], **chamfer))
    axes.add_patch(RegularPolygon((0.8, 0.7), 6, radius=0.11, orientation=0.2, **round_))
    axes.add_patch(Rectangle((0.63, 0.84), 0.34, 0.12, angle=-4, **chamfer))
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    red, green, blue = np.moveaxis(np.asarray(canvas.buffer_rgba())[..., :3] > 127, -1, 0)
    return red & ~green, blue & ~green
