"""Local frames for geometry images (the paper's fix for tangential drift, section 6) and for
normal maps.

The Hausdorff distance between surfaces hardly sees an error that slides a point along the
surface, but the L2 error of the three position channels counts it in full. The detail
coefficients of the positions are therefore expressed, at every place, in a local frame
(normal, first tangent, second tangent), and the normal component is multiplied by a weight
``w`` before the basis search and the quantization, and divided by it after: its error is
``w`` times smaller for the same threshold. The paper uses 3; 2 measures a little better
(``benchmarks/rd_meshes.py``) and is the default of :func:`bandelets.encode`.

The decoder must know the frames of a level before it can turn its details back, so they come
from what it has decoded before them: the approximation and the coarser levels, dequantized
and back in the global frame. Their wavelet reconstruction (every finer detail set to 0) is a
smooth surface at full resolution; the tangents are its differences between neighbouring
pixels along the columns and along the rows, the normal their cross product. A detail
coefficient of level ``j`` at ``(i, k)`` of its subband takes the frame of pixel
``(2**j i + 2**(j-1), 2**j k + 2**(j-1))``.
Each rotation is orthonormal, so the coefficients keep their energy and the Lagrangian and
the quantizer work unchanged on them.

Normal maps coded with their three channels (normals facing every way, as those of closed
meshes) are coded in local frames too, a step beyond the paper: the details of a field of unit
vectors are nearly tangent to it (``n . dn = 0``), and the decoder renormalises every vector,
which takes off most of an error along it. So the frame's normal is the coarse decoded normal
itself (:func:`normal_map_frames`), the component along it is small (of second order) and is
coded with the weight :data:`bandelets.format.header.NORMAL_MAP_WEIGHT`. On the 256 x 256 normal
maps of fandisk and bunny (restored both ways) this gained +0.6 and +0.5 dB BD-PSNR against every anchor of
``python benchmarks/rd_surfaces.py --only mesh-normals`` over coding x, y, z as they are. The
weight was chosen among 0.25, 0.35, 0.5 and 0.7 in prototype runs (scripts not kept): +0.60 /
+0.62 / +0.56 / +0.30 dB on fandisk, +0.45 / +0.53 / +0.48 / - on bunny.

The first tangent of a normal map's frame is the direction along which the coarse normals turn
most around that place (format version 13): at a crease between two facets the details of the
normals all point one way in the tangent plane (from one facet's normal to the other's), so that
one tangential channel holds them and the other is left nearly empty, much as AV1 predicts its
chroma from its luma. The decoder finds the same direction in what it has decoded before, so it
costs no bits. Over the x axis projected on the tangent plane it gained +0.37 dB BD-PSNR on
fandisk's normal map at 256 (+0.1 dB at 0.25 bpp to +0.75 at 2 bpp) and +0.11 dB on bunny's, at
512 +0.57 and +0.22 dB (BENCHMARKS, "Frames along the crease").
"""

from __future__ import annotations

import numpy as np

from ..format.fields import Kind
from .wavelets import subband_slices, waverec

__all__ = [
    "frame_field",
    "normal_map_frames",
    "level_frames",
    "rotate",
    "rotate_levels",
    "to_global",
]

# The cross product of the tangents is taken as degenerate below this fraction of the
# product of their lengths (tangents parallel), or when either tangent is zero.
_DEGENERATE = 1e-9
# A normal map's tangent is the x axis projected on the tangent plane, or the y axis where the
# normal is this close to +-x.
_NEAR_AXIS = 1e-3
#: Where the coarse normals hardly turn, a normal map's tangent stays near the x axis projected on
#: the tangent plane: this is added to its turning (squared differences of unit vectors) at each
#: step of :func:`normal_map_frames` (1e-4 and 1e-3 measured alike on fandisk and bunny, 3e-3 lost
#: 0.05 dB BD-PSNR on fandisk, 1e-2 0.1 to 0.2 dB).
TURNING_FLOOR = 1e-3
#: Power iteration steps towards the direction of largest turning.
_TURNING_STEPS = 2


def frame_field(du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Orthonormal frames from the tangents of a surface.

    Parameters
    ----------
    du, dv : ndarray of float, shape (..., 3)
        Tangents along the columns and along the rows (any lengths).

    Returns
    -------
    ndarray of float, shape (..., 3, 3)
        ``[..., 0, :]`` the unit normal, ``[..., 1, :]`` the unit tangent along the columns,
        ``[..., 2, :]`` their cross product. Where the surface is degenerate (a tangent is 0,
        or the two are parallel) the frame is fixed: normal z, tangents x and y, so that the
        encoder and the decoder agree whatever the data.
    """
    normal = np.cross(du, dv)
    length_n = np.linalg.norm(normal, axis=-1, keepdims=True)
    length_u = np.linalg.norm(du, axis=-1, keepdims=True)
    length_v = np.linalg.norm(dv, axis=-1, keepdims=True)
    good = (length_n > _DEGENERATE * length_u * length_v) & (length_u > 0) & (length_v > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = np.where(good, normal / length_n, (0.0, 0.0, 1.0))
        tangent = np.where(good, du / length_u, (1.0, 0.0, 0.0))
    # du is orthogonal to du x dv already: the cross product completes the frame.
    return np.stack([normal, tangent, np.cross(normal, tangent)], axis=-2)


def normal_map_frames(
    normals: np.ndarray, du: np.ndarray | None = None, dv: np.ndarray | None = None
) -> np.ndarray:
    """Orthonormal frames around the vectors of a normal map.

    Parameters
    ----------
    normals : ndarray of float, shape (H, W, 3)
        Any lengths.
    du, dv : ndarray of float, shape (H, W, 3), optional
        Differences of the normals between neighbours along the columns and along the rows.

    Returns
    -------
    ndarray of float, shape (H, W, 3, 3)
        ``[..., 0, :]`` the unit vector of ``normals`` (z where it is 0); ``[..., 1, :]`` the x
        axis projected on the plane orthogonal to it (the y axis where the normal is along x),
        or with ``du, dv`` the direction of that plane along which the normals turn most over
        the 3 x 3 neighbours (the principal axis of the sum of their ``du du^T + dv dv^T``,
        projected on the plane, by :data:`_TURNING_STEPS` power iteration steps from the axis
        projected, so that its sign follows it, with :data:`TURNING_FLOOR` added at each step);
        ``[..., 2, :]`` their cross product. The tangents turn smoothly with the normals, so
        that the tangential details stay as sparse as the normals are smooth.
    """
    normal = _unit(normals)
    # An axis minus its component along the normal.
    tx = (1.0, 0.0, 0.0) - normal[..., 0:1] * normal
    ty = (0.0, 1.0, 0.0) - normal[..., 1:2] * normal
    lx, ly = (np.linalg.norm(t, axis=-1, keepdims=True) for t in (tx, ty))
    with np.errstate(invalid="ignore", divide="ignore"):
        tangent = np.where(lx > _NEAR_AXIS, tx / lx, ty / ly)
    if du is not None and dv is not None:
        tangent = _turning(normal, tangent, du, dv)
    return np.stack([normal, tangent, np.cross(normal, tangent)], axis=-2)


def _unit(v: np.ndarray) -> np.ndarray:
    """The unit vectors of ``v`` (..., 3), z where a vector is 0."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(length > _DEGENERATE, v / length, (0.0, 0.0, 1.0))


def _along(v: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``v`` (..., 3) less its component along the unit ``normal``."""
    return v - np.sum(v * normal, axis=-1, keepdims=True) * normal


def _turning(normal: np.ndarray, start: np.ndarray, du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """The unit tangents of :func:`normal_map_frames` with ``du, dv`` (all shape (H, W, 3)).

    Written with elementwise products, not einsum, so that every platform sums in one order."""
    with np.errstate(under="ignore"):  # a product below the smallest float is 0 alike
        return _turned(normal, start, _along(du, normal), _along(dv, normal))


def _turned(normal: np.ndarray, start: np.ndarray, du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    # The symmetric tensor du du^T + dv dv^T (its 6 entries), averaged over the 3 x 3 neighbours.
    pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    h, w = normal.shape[:2]
    averaged = {}
    for i, j in pairs:
        padded = np.pad(du[..., i] * du[..., j] + dv[..., i] * dv[..., j], 1, mode="edge")
        rows = padded[:h] + padded[1 : h + 1] + padded[2 : h + 2]
        averaged[i, j] = averaged[j, i] = (rows[:, :w] + rows[:, 1 : w + 1] + rows[:, 2 : w + 2]) / 9.0
    tangent = start
    for _ in range(_TURNING_STEPS):
        turned = np.stack([sum(averaged[i, j] * tangent[..., j] for j in range(3)) for i in range(3)], -1)
        tangent = _along(turned, normal) + TURNING_FLOOR * tangent
        tangent /= np.linalg.norm(tangent, axis=-1, keepdims=True)
    return tangent


def level_frames(
    coefficients: list[np.ndarray],
    level: int,
    wavelet: str,
    levels: int,
    extension: str,
    kind: Kind = Kind.GEOMETRY_IMAGE,
) -> np.ndarray:
    """The frame of every position of the detail subbands of ``level`` (1 = finest).

    Parameters
    ----------
    coefficients : list of 3 ndarray, shape (H, W)
        Normalised wavelet coefficients of x, y, z (Mallat layout); only the approximation and
        the levels coarser than ``level`` are read, in the global frame.
    level : int
    wavelet, levels, extension
        The transform of ``coefficients`` (:func:`bandelets.transform.wavelets.waverec`).
    kind : {"geometry-image", "normal-map"}
        What x, y, z are: positions (frames from the tangents, :func:`frame_field`) or normals
        (frames around them, :func:`normal_map_frames`).

    Returns
    -------
    ndarray of float, shape (H / 2**level, W / 2**level, 3, 3)
        Rows normal, tangent, tangent.
    """
    shape = coefficients[0].shape
    h, w = shape[0] >> level, shape[1] >> level
    surface = np.empty(shape + (3,))
    for k, c in enumerate(coefficients):
        coarse = np.zeros(shape)
        coarse[:h, :w] = c[:h, :w]
        surface[..., k] = waverec(coarse, wavelet, levels, extension)
    rows = np.minimum((np.arange(h) << level) + (1 << (level - 1)), shape[0] - 1)
    cols = np.minimum((np.arange(w) << level) + (1 << (level - 1)), shape[1] - 1)
    if kind == Kind.NORMAL_MAP:  # differences over the level's half step (one-sided on the border)
        step = 1 << (level - 1)
        right, left = np.minimum(cols + step, shape[1] - 1), np.maximum(cols - step, 0)
        down, up = np.minimum(rows + step, shape[0] - 1), np.maximum(rows - step, 0)
        # Of unit vectors: bounded whatever a file holds.
        du = _unit(surface[np.ix_(rows, right)]) - _unit(surface[np.ix_(rows, left)])
        dv = _unit(surface[np.ix_(down, cols)]) - _unit(surface[np.ix_(up, cols)])
        return normal_map_frames(surface[np.ix_(rows, cols)], du, dv)
    # Differences of the neighbouring pixels (one-sided on the border); only their
    # directions matter.
    right, left = np.minimum(cols + 1, shape[1] - 1), np.maximum(cols - 1, 0)
    down, up = np.minimum(rows + 1, shape[0] - 1), np.maximum(rows - 1, 0)
    du = surface[np.ix_(rows, right)] - surface[np.ix_(rows, left)]
    dv = surface[np.ix_(down, cols)] - surface[np.ix_(up, cols)]
    return frame_field(du, dv)


def rotate(
    coefficients: list[np.ndarray], frames: np.ndarray, level: int, levels: int, weight: float, *, local: bool
) -> None:
    """Turn the three detail subbands of ``level`` into (``local``) or out of the frames, in place.

    Parameters
    ----------
    coefficients : list of 3 ndarray, shape (H, W)
        Channels x, y, z; in the local frames, normal (times ``weight``), tangent, tangent.
    frames : ndarray, shape (H / 2**level, W / 2**level, 3, 3)
        :func:`level_frames`.
    level, levels : int
    weight : float
        Factor of the normal component.
    local : bool
        True: global to local; False: back.
    """
    shape = coefficients[0].shape
    scale = (weight, 1.0, 1.0)
    # Written out rather than with einsum over (..., 3, 3): three times faster, and the
    # restoration turns every level twice per iteration.
    for where in (s for lv, _, s in subband_slices(shape, levels) if lv == level):
        v = [c[where] for c in coefficients]
        if local:
            out = [sum(frames[..., i, j] * v[j] for j in range(3)) * scale[i] for i in range(3)]
        else:
            v = [v[j] / scale[j] for j in range(3)]
            out = [sum(frames[..., j, i] * v[j] for j in range(3)) for i in range(3)]
        for c, turned in zip(coefficients, out, strict=True):
            c[where] = turned


def to_global(
    coefficients: list[np.ndarray],
    wavelet: str,
    levels: int,
    extension: str,
    weight: float,
    kind: Kind = Kind.GEOMETRY_IMAGE,
) -> dict[int, np.ndarray]:
    """Every level back from the local frames, coarsest first (as the decoder does), in place.

    ``coefficients`` (3 arrays, shape (H, W), local frames) hold the decoded values; the
    frames of each level come from the levels already turned back. Returns those frames, by
    level (:func:`level_frames` of ``kind``), for :func:`rotate_levels`.
    """
    out = {}
    for level in range(levels, 0, -1):
        out[level] = level_frames(coefficients, level, wavelet, levels, extension, kind)
        rotate(coefficients, out[level], level, levels, weight, local=False)
    return out


def rotate_levels(
    coefficients: list[np.ndarray], frames: dict[int, np.ndarray], levels: int, weight: float, *, local: bool
) -> None:
    """:func:`rotate` every level with fixed ``frames`` (from :func:`to_global`), in place."""
    for level in range(levels, 0, -1):
        rotate(coefficients, frames[level], level, levels, weight, local=local)
