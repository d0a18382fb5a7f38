"""Coarse-to-fine support of the spherical parameterization: nested decimations, and fine
vertices placed on the sphere map of a coarser mesh.

Praun and Hoppe (2003) map a progressive mesh's base to the sphere and insert the vertices
back one by one. Here the hierarchy has a few levels instead, each a quadric-error decimation
(pymeshlab, MeshLab's edge collapse) of the one above it, about four times smaller, with
*no* optimal placement: every vertex of a level is a vertex of the level above, so a level is
a subset of the original vertices and the sphere points found on it are kept when the next
level is mapped. The other vertices of the finer level are placed by their closest point on
the coarser surface: its triangle and barycentric weights carry it onto the coarser level's
spherical triangle. No library returns closest points on a triangle mesh without an extra
dependency (trimesh needs rtree), so the query is written here: candidates are the triangles
around the nearest coarse vertices (scipy's cKDTree), tested exactly in a numba loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

from .meshlab import confined

__all__ = ["decimate", "levels", "place"]

_RATIO = 4  # vertices of a level over those of the next coarser one
_CANDIDATES = 12  # nearest coarse vertices whose triangles are tried for a closest point
# Levels of more vertices are decimated without MeshLab's check that no collapse turns a face's
# normal over: on the 55,730-vertex bunny of benchmarks/mesh_pipeline.py that check is half of
# the first decimation's time (2.0 against 3.4 s of CPU), and the map is as good (stretch 1.257
# against 1.254, Hausdorff PSNR at 4 bits per vertex 83.41 against 82.37 dB). The shared meshes
# (up to 19,970 vertices) keep it.
_NORMALS_CHECKED_UP_TO = 30_000


@confined
def decimate(
    vertices: np.ndarray, faces: np.ndarray, count: int, normals: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Quadric-error decimation to about ``count`` vertices that keeps vertices in place.

    Parameters
    ----------
    vertices : ndarray of float, shape (V, 3)
    faces : ndarray of int, shape (F, 3)
        A closed genus-0 mesh (its topology is preserved).
    count : int
    normals : bool
        Refuse the collapses that turn a face's normal over (MeshLab's ``preservenormal``).

    Returns
    -------
    kept : ndarray of int, shape (V',)
        Indices of the vertices kept.
    faces : ndarray of int, shape (2 V' - 4, 3)
        The decimated triangles, indexing ``kept``.
    """
    import pymeshlab
    from scipy.spatial import cKDTree

    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(pymeshlab.Mesh(vertices, faces.astype(np.int32)))
    meshset.meshing_decimation_quadric_edge_collapse(
        targetfacenum=2 * count - 4,
        optimalplacement=False,
        preservetopology=True,
        preservenormal=normals,
        qualitythr=0.3,
    )
    coarse = meshset.current_mesh()
    distance, kept = cKDTree(vertices).query(coarse.vertex_matrix())
    if np.any(distance > 0) or len(np.unique(kept)) != len(kept):  # not expected: MeshLab moved a vertex
        raise ValueError("decimation moved vertices")
    return kept, np.asarray(coarse.face_matrix(), dtype=np.int64)


def levels(vertices: np.ndarray, faces: np.ndarray, coarsest: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Nested decimations, finest (the mesh itself) first, down to about ``coarsest`` vertices.

    Returns
    -------
    list of (kept, faces)
        ``kept`` (int, shape (V_l,)) indexes the original vertices, ``faces`` (int, shape
        (F_l, 3)) indexes ``kept``; each level's ``kept`` is a subset of the previous one's.
    """
    result = [(np.arange(len(vertices)), faces)]
    while len(result[-1][0]) > _RATIO * coarsest // 2:
        kept, level_faces = result[-1]
        count = max(coarsest, len(kept) // _RATIO)
        sub, sub_faces = decimate(vertices[kept], level_faces, count, len(kept) <= _NORMALS_CHECKED_UP_TO)
        if len(sub) >= len(kept):
            break
        result.append((kept[sub], sub_faces))
    return result


@intrinsic
def _fma(typingctx, x, y, z):
    """``x * y + z`` rounded once (LLVM's ``llvm.fma``)."""
    from llvmlite import ir

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        function = builder.module.declare_intrinsic(
            "llvm.fma", [double], ir.FunctionType(double, [double] * 3)
        )
        return builder.call(function, args)

    return types.float64(types.float64, types.float64, types.float64), codegen


@njit(cache=True, inline="always")
def _dot(x0, x1, x2, y0, y1, y2):
    """The dot product as numba's ``@`` of two 3-vectors rounds it (OpenBLAS's ``ddot``: fused
    multiply-adds, in order): the placements stay those of the vector code before, bit for bit,
    and are now the same on every CPU (``llvm.fma`` rounds once, in hardware or in libm's ``fma``).
    Another rounding moves them by 1e-16, and the relaxation after them ends elsewhere (up to
    0.5 dB apart on the shared meshes at 0.5 bits per vertex, either way)."""
    return _fma(x2, y2, _fma(x1, y1, x0 * y0))


@njit(cache=True)
def _closest_on_triangle(p, vertices, ia, ib, ic):
    """Barycentric weights and squared distance of the point of triangle ``vertices[[ia, ib,
    ic]]`` closest to p (Ericson, Real-Time Collision Detection, 5.1.5); in scalars, as the
    small arrays of vector arithmetic cost an allocation each (eight times the time), each
    rounded as the vector code rounded it."""
    ax, ay, az = vertices[ia, 0], vertices[ia, 1], vertices[ia, 2]
    abx, aby, abz = vertices[ib, 0] - ax, vertices[ib, 1] - ay, vertices[ib, 2] - az
    acx, acy, acz = vertices[ic, 0] - ax, vertices[ic, 1] - ay, vertices[ic, 2] - az
    apx, apy, apz = p[0] - ax, p[1] - ay, p[2] - az
    d1, d2 = _dot(abx, aby, abz, apx, apy, apz), _dot(acx, acy, acz, apx, apy, apz)
    w0, w1, w2 = 1.0, 0.0, 0.0
    if not (d1 <= 0 and d2 <= 0):
        bpx, bpy, bpz = p[0] - vertices[ib, 0], p[1] - vertices[ib, 1], p[2] - vertices[ib, 2]
        cpx, cpy, cpz = p[0] - vertices[ic, 0], p[1] - vertices[ic, 1], p[2] - vertices[ic, 2]
        d3, d4 = _dot(abx, aby, abz, bpx, bpy, bpz), _dot(acx, acy, acz, bpx, bpy, bpz)
        d5, d6 = _dot(abx, aby, abz, cpx, cpy, cpz), _dot(acx, acy, acz, cpx, cpy, cpz)
        va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
        if d3 >= 0 and d4 <= d3:
            w0, w1, w2 = 0.0, 1.0, 0.0
        elif d6 >= 0 and d5 <= d6:
            w0, w1, w2 = 0.0, 0.0, 1.0
        elif vc <= 0 and d1 >= 0 and d3 <= 0:
            t = d1 / (d1 - d3)
            w0, w1, w2 = 1.0 - t, t, 0.0
        elif vb <= 0 and d2 >= 0 and d6 <= 0:
            t = d2 / (d2 - d6)
            w0, w1, w2 = 1.0 - t, 0.0, t
        elif va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
            t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            w0, w1, w2 = 0.0, 1.0 - t, t
        else:
            denominator = va + vb + vc
            if denominator <= 0:  # degenerate triangle
                w0, w1, w2 = 1.0 / 3, 1.0 / 3, 1.0 / 3
            else:
                w0, w1, w2 = va / denominator, vb / denominator, vc / denominator
    # p - q, q = w0 a + w1 b + w2 c
    dx = p[0] - (w0 * ax + w1 * vertices[ib, 0] + w2 * vertices[ic, 0])
    dy = p[1] - (w0 * ay + w1 * vertices[ib, 1] + w2 * vertices[ic, 1])
    dz = p[2] - (w0 * az + w1 * vertices[ib, 2] + w2 * vertices[ic, 2])
    return w0, w1, w2, _dot(dx, dy, dz, dx, dy, dz)


@njit(cache=True)
def _closest(queries, vertices, faces, candidate_vertices, vertex_faces, offsets):
    """For each query the (face, weights) of its closest point among the triangles around
    its candidate vertices; vertex ``v``'s triangles are ``vertex_faces[offsets[v]:offsets[v+1]]``."""
    n = queries.shape[0]
    face = np.empty(n, dtype=np.int64)
    weights = np.empty((n, 3))
    for i in range(n):
        best = np.inf
        for v in candidate_vertices[i]:
            for k in range(offsets[v], offsets[v + 1]):
                f = vertex_faces[k]
                w0, w1, w2, d = _closest_on_triangle(
                    queries[i], vertices, faces[f, 0], faces[f, 1], faces[f, 2]
                )
                if d < best:
                    best = d
                    face[i] = f
                    weights[i, 0], weights[i, 1], weights[i, 2] = w0, w1, w2
    return face, weights


def place(queries: np.ndarray, vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Sphere points of ``queries`` through their closest points on a mapped coarse mesh.

    Parameters
    ----------
    queries : ndarray of float, shape (Q, 3)
        Positions to place.
    vertices : ndarray of float, shape (V, 3)
        The coarse mesh's positions.
    faces : ndarray of int, shape (F, 3)
    points : ndarray of float, shape (V, 3)
        The coarse mesh's sphere map (unit vectors).

    Returns
    -------
    ndarray of float, shape (Q, 3)
        Unit vectors: the closest point's barycentric weights applied to its triangle's
        corners on the sphere, normalised.
    """
    from scipy.spatial import cKDTree

    k = min(_CANDIDATES, len(vertices))
    candidates = cKDTree(vertices).query(queries, k=k)[1].reshape(len(queries), k)
    order = np.argsort(faces.ravel(), kind="stable")
    offsets = np.searchsorted(faces.ravel()[order], np.arange(len(vertices) + 1))
    face, weights = _closest(
        np.ascontiguousarray(queries, dtype=np.float64),
        np.ascontiguousarray(vertices, dtype=np.float64),
        np.ascontiguousarray(faces, dtype=np.int64),
        np.ascontiguousarray(candidates, dtype=np.int64),
        order // 3,
        offsets,
    )
    placed = np.einsum("qk,qkc->qc", weights, points[faces[face]])
    return placed / np.maximum(np.linalg.norm(placed, axis=1, keepdims=True), 1e-300)


def interpolate(laplacian, kept: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Sphere points of a level's vertices by harmonic interpolation of the coarser level's.

    Parameters
    ----------
    laplacian : sparse matrix, shape (V, V)
        The finer level's Laplacian (positive weights).
    kept : ndarray of int, shape (V',)
        The coarser level's vertices, as indices of the finer level's.
    points : ndarray of float, shape (V', 3)
        Their sphere points.

    Returns
    -------
    ndarray of float, shape (V, 3)
        The kept vertices at their points, the others solving ``L x = 0``, normalised.
    """
    from scipy.sparse.linalg import spsolve

    lap = laplacian.tocsr()
    free = np.setdiff1d(np.arange(lap.shape[0]), kept)
    result = np.empty((lap.shape[0], 3))
    result[kept] = points
    rhs = -(lap[free][:, kept] @ points)
    result[free] = spsolve(lap[free][:, free].tocsc(), rhs)
    return result / np.maximum(np.linalg.norm(result, axis=1, keepdims=True), 1e-300)
