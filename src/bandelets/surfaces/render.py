"""Object-space normal maps rendered from a mesh: what a baker writes for a view of the part.

:func:`render_normals` looks at a mesh along a direction, orthographically, the mesh fitted to
the square with a margin, and gives each pixel the object-space unit normal of the surface it
sees, antialiased: ``supersampling x supersampling`` samples per pixel, each the normal of the
nearest front-facing triangle there, averaged as a renderer resolves its samples (not
renormalised: a pixel on a silhouette is the mean of what it covers). Where no surface is seen
the map holds ``background``: ``(0, 0, 1)`` by default, the flat normal a tangent-space baker
writes. The zero vector a float renderer writes for an empty pixel is a trap in 16-bit samples:
``(32768, 32768, 32768)`` is a vector of length 1.5e-5 whose direction, once renormalised (as
every PSNR here measures it, and a shader does), any error of one sample turns anywhere; the
anchors' PSNR collapses on it (AVIF 9 to 21 dB on the rendered fandisk at 256, BENCHMARKS).
The coder takes it (the encoder renormalises it to ``(1, 1, 1) / sqrt(3)``, a zero float vector
to +z) without a NaN.

The normals are the mesh's vertex normals interpolated across each triangle (what a baker gives
a smooth-shaded mesh), split along edges sharper than ``crease_angle``: a CAD exporter writes
its faces' patches with their own normals, so a CAD mesh's creases stay sharp and its curved
patches smooth (``crease_angle=45`` on ``fandisk.off``, whose feature edges are all near 90
degrees and whose other edges below 10), while a scan is shaded smooth everywhere (the
default). ``crease_angle=0`` is flat shading: every triangle shows, which no baker gives a
curved CAD patch.

The rasterizer is a small z-buffer kernel compiled with numba, written here because no library
the project depends on rasterizes without a window or a GPU: trimesh's ray casting needs rtree
or embree (neither is a dependency), pymeshlab renders nothing, and a z-buffer of a few
thousand triangles at 2048^2 samples takes well under a second. It is deterministic: pixel
centres tested against each triangle in face order, the nearest kept, ties to the first.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["corner_normals", "render_normals", "to_samples", "turned_up"]


def corner_normals(vertices: np.ndarray, faces: np.ndarray, crease_angle: float = 180.0) -> np.ndarray:
    """The normal at each corner of each triangle: the area-weighted mean of the normals of the
    triangles around that corner's vertex that lie within ``crease_angle`` degrees of this
    triangle's (the triangle itself always does).

    Parameters
    ----------
    vertices : ndarray, shape (V, 3)
    faces : ndarray of int, shape (F, 3)
    crease_angle : float
        Degrees; 0 is flat shading, 180 (the default) smooth shading everywhere.

    Returns
    -------
    ndarray of float64, shape (F, 3, 3): unit normal of corner ``k`` of face ``f`` at ``[f, k]``.
    """
    vertices, faces = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    cross = np.cross(
        vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]]
    )
    length = np.linalg.norm(cross, axis=1, keepdims=True)
    unit = cross / np.where(length > 0, length, 1.0)
    # Faces around each vertex, as rows padded with -1.
    corner_vertex = faces.ravel()
    order = np.argsort(corner_vertex, kind="stable")
    counts = np.bincount(corner_vertex, minlength=len(vertices))
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    slot = np.arange(len(order)) - starts[corner_vertex[order]]
    around = np.full((len(vertices), max(int(counts.max()), 1)), -1, np.int64)
    around[corner_vertex[order], slot] = order // 3
    neighbours = around[corner_vertex]  # (3F, D)
    own = np.repeat(unit, 3, axis=0)  # (3F, 3)
    valid = neighbours >= 0
    near = np.einsum("cdk,ck->cd", unit[neighbours], own) >= np.cos(np.radians(crease_angle)) - 1e-12
    weights = np.where(valid & near, length[neighbours, 0], 0.0)
    total = np.einsum("cd,cdk->ck", weights, unit[neighbours])
    norm = np.linalg.norm(total, axis=1, keepdims=True)
    total = np.where(norm > 0, total / np.where(norm > 0, norm, 1.0), own)
    return total.reshape(len(faces), 3, 3)


@njit(cache=True)
def _rasterize(u, v, depth, faces, normals, facing, zbuffer, out):  # pragma: no cover - compiled
    rows, cols = zbuffer.shape
    for f in range(faces.shape[0]):
        if not facing[f]:
            continue
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        area = (u[b] - u[a]) * (v[c] - v[a]) - (u[c] - u[a]) * (v[b] - v[a])
        if area == 0.0:
            continue
        low_col = max(int(np.floor(min(u[a], u[b], u[c]) - 0.5)), 0)
        high_col = min(int(np.ceil(max(u[a], u[b], u[c]) - 0.5)), cols - 1)
        low_row = max(int(np.floor(min(v[a], v[b], v[c]) - 0.5)), 0)
        high_row = min(int(np.ceil(max(v[a], v[b], v[c]) - 0.5)), rows - 1)
        for row in range(low_row, high_row + 1):
            y = row + 0.5
            for col in range(low_col, high_col + 1):
                x = col + 0.5
                wa = ((u[b] - x) * (v[c] - y) - (u[c] - x) * (v[b] - y)) / area
                wb = ((u[c] - x) * (v[a] - y) - (u[a] - x) * (v[c] - y)) / area
                wc = 1.0 - wa - wb
                if wa < 0.0 or wb < 0.0 or wc < 0.0:
                    continue
                z = wa * depth[a] + wb * depth[b] + wc * depth[c]
                if z <= zbuffer[row, col]:
                    continue
                zbuffer[row, col] = z
                n0 = wa * normals[f, 0, 0] + wb * normals[f, 1, 0] + wc * normals[f, 2, 0]
                n1 = wa * normals[f, 0, 1] + wb * normals[f, 1, 1] + wc * normals[f, 2, 1]
                n2 = wa * normals[f, 0, 2] + wb * normals[f, 1, 2] + wc * normals[f, 2, 2]
                norm = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
                if norm > 0.0:
                    out[row, col, 0] = n0 / norm
                    out[row, col, 1] = n1 / norm
                    out[row, col, 2] = n2 / norm


def turned_up(vertices: np.ndarray, up: str) -> np.ndarray:
    """``vertices`` (V, 3) rotated so that the axis ``up`` (``"+x"``, ``"-x"``, ..., ``"-z"``) points
    along +z: a part set on the table the way its top view is taken (a rotation, so the normals
    turn with it and stay object-space normals of the turned part)."""
    sign, axis = (-1.0 if up[0] == "-" else 1.0), "xyz".index(up[-1])
    rows = {  # rows of a rotation matrix taking +axis (sign +1) to +z
        0: ((0, 0, -1), (0, 1, 0), (1, 0, 0)),
        1: ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
        2: ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    }[axis]
    rotation = np.array(rows, np.float64)
    if sign < 0:  # half a turn about an axis orthogonal to z first
        rotation = rotation * np.array([[1.0], [-1.0], [-1.0]])
    return np.asarray(vertices, np.float64) @ rotation.T


def _frame(view: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The image's right and up axes for a camera looking along ``-view``: up is world +y
    (world +z when looking along y), so the top view (``view`` +z) has x right and y up."""
    reference = np.array([0.0, 0.0, 1.0]) if abs(view[1]) > 0.99 else np.array([0.0, 1.0, 0.0])
    up = reference - (reference @ view) * view
    up /= np.linalg.norm(up)
    return np.cross(up, view), up


def render_normals(
    vertices: np.ndarray,
    faces: np.ndarray,
    size: int = 512,
    view=(0.0, 0.0, 1.0),
    crease_angle: float = 180.0,
    supersampling: int = 4,
    margin: float = 0.04,
    background=(0.0, 0.0, 1.0),
) -> np.ndarray:
    """The object-space normal map of a mesh seen along ``-view`` (see the module notes).

    Parameters
    ----------
    vertices : ndarray, shape (V, 3)
    faces : ndarray of int, shape (F, 3)
    size : int
        Side of the map in pixels.
    view : sequence of 3 floats
        Direction towards the camera, in object space (normalised here); ``(0, 0, 1)``: the top view.
    crease_angle : float
        Degrees (:func:`corner_normals`).
    supersampling : int
        Samples per pixel side (1: one sample at each pixel centre, aliased edges).
    margin : float
        Empty border on each side of the mesh's extent, a fraction of the side.
    background : sequence of 3 floats
        The vector where no surface is seen.

    Returns
    -------
    ndarray of float64, shape (size, size, 3): row 0 at the top of the view; unit vectors where
    the surface covers the whole pixel, shorter on silhouettes (averaged with ``background``).
    """
    vertices, faces = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    view = np.asarray(view, np.float64)
    if size < 1 or supersampling < 1 or not 0.0 <= margin < 0.5:
        raise ValueError("size and supersampling must be positive and margin in [0, 0.5)")
    if view.shape != (3,) or not np.all(np.isfinite(view)) or not np.any(view):
        raise ValueError(f"view must be a nonzero direction of 3 finite numbers, got {view.tolist()}")
    view = view / np.linalg.norm(view)
    right, up = _frame(view)
    fine = size * supersampling
    across, along = vertices @ right, vertices @ up
    extent = max(np.ptp(across), np.ptp(along), np.finfo(float).tiny)
    scale = fine * (1.0 - 2.0 * margin) / extent
    u = (across - (across.max() + across.min()) / 2.0) * scale + fine / 2.0
    v = ((along.max() + along.min()) / 2.0 - along) * scale + fine / 2.0
    normals = corner_normals(vertices, faces, crease_angle)
    cross = np.cross(
        vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]]
    )
    facing = cross @ view > 0.0
    zbuffer = np.full((fine, fine), -np.inf)
    samples = np.empty((fine, fine, 3))
    samples[...] = np.asarray(background, np.float64)
    _rasterize(u, v, vertices @ view, faces, normals, facing, zbuffer, samples)
    return samples.reshape(size, supersampling, size, supersampling, 3).mean(axis=(1, 3))


def to_samples(normals: np.ndarray, depth: int = 16) -> np.ndarray:
    """Vectors in ``[-1, 1]`` as unsigned samples of ``depth`` bits, ``rint((n + 1) / 2 * top)``,
    as a baker writes them (the zero vector is ``2 ** (depth - 1)``).

    Returns
    -------
    ndarray of uint16 (depth 16) or uint8 (depth 8), shape of ``normals``.
    """
    top = 2**depth - 1
    values = np.rint((np.clip(normals, -1.0, 1.0) + 1.0) / 2.0 * top)
    return values.astype(np.uint16 if depth == 16 else np.uint8)
