"""Spherical geometry images: sampling a mesh on the octahedral grid, and the mesh back.

A geometry image of side ``n`` holds, at the pixel centres of the unfolded octahedron
(:func:`bandelets.surfaces.octahedral.grid`), the surface point whose spherical image is that
pixel's sphere point. It is rebuilt as a mesh with one vertex per pixel, two triangles per
pixel square (split along the octahedron's edges), and the border glued as the unfolding
prescribes: pixel ``(0, j)`` neighbours ``(0, n-1-j)`` across the top edge, likewise on the
other three edges, and the four corner pixels surround the south pole. The mesh is closed and
crack-free whatever values the image holds.

:func:`decimate` brings that mesh down to a chosen vertex count by quadric edge collapse
(fast-simplification, MeshLab's where that one breaks the topology), keeping its topology: a
closed genus-0 mesh stays one. A grid far denser than the target is first halved (:func:`coarsen`).
"""

from __future__ import annotations

import threading

import numpy as np
from numba import njit

from . import octahedral
from .meshlab import confined

__all__ = ["coarsen", "decimate", "decimate_meshlab", "locate", "mesh_from_image", "sample", "triangulation"]


def _neighbours(faces: np.ndarray) -> np.ndarray:
    """Face across the edge opposite each corner, shape (F, 3), for a closed oriented mesh."""
    n = int(faces.max()) + 1
    start = faces[:, [1, 2, 0]].astype(np.int64)  # edge opposite corner k runs k+1 -> k+2
    end = faces[:, [2, 0, 1]].astype(np.int64)
    key = (start * n + end).ravel()
    order = np.argsort(key)
    where = np.searchsorted(key[order], (end * n + start).ravel()).clip(0, key.size - 1)
    return (order[where] // 3).reshape(faces.shape)


@njit(cache=True, inline="always")
def _side(q, points, a, b):
    """``q . (points[a] x points[b])``: positive when ``q`` is on the inner side of edge ab."""
    ax, ay, az = points[a, 0], points[a, 1], points[a, 2]
    bx, by, bz = points[b, 0], points[b, 1], points[b, 2]
    return q[0] * (ay * bz - az * by) + q[1] * (az * bx - ax * bz) + q[2] * (ax * by - ay * bx)


@njit(cache=True)
def _walk(faces, points, neighbours, queries, starts, most_steps):
    """Each query's triangle, walking from ``starts[i]`` (if -1: the previous query's
    triangle) across the edge whose side test fails worst, until none fails; -1 for a query
    that did not arrive in ``most_steps``. Queries in scan order (neighbouring pixels) make
    most walks from the previous one zero or one step."""
    found = np.empty(len(queries), dtype=np.int64)
    current = 0
    for i in range(len(queries)):
        q = queries[i]
        if starts[i] >= 0:
            current = starts[i]
        elif current < 0:
            current = 0
        for _ in range(most_steps):
            a, b, c = faces[current, 0], faces[current, 1], faces[current, 2]
            t0, t1, t2 = _side(q, points, b, c), _side(q, points, c, a), _side(q, points, a, b)
            worst, value = 0, t0
            if t1 < value:
                worst, value = 1, t1
            if t2 < value:
                worst, value = 2, t2
            if value >= 0:
                break
            current = neighbours[current, worst]
        else:
            current = -1
        found[i] = current
    return found


def locate(faces: np.ndarray, points: np.ndarray, queries: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Find the spherical triangle holding each query direction, and its barycentric weights.

    Walks from the previous query's triangle towards each query (:func:`_walk`), crossing the
    edge whose side test fails worst; the few that do not arrive in time walk again from the
    triangle of their nearest vertex, and those that still do not are tested against every
    triangle.

    Parameters
    ----------
    faces : ndarray of int, shape (F, 3)
    points : ndarray of float, shape (V, 3)
        A flip-free spherical triangulation (unit vectors).
    queries : ndarray of float, shape (Q, 3)
        Unit vectors, best in an order where neighbours follow each other.

    Returns
    -------
    face : ndarray of int, shape (Q,)
    weights : ndarray of float, shape (Q, 3)
        Non-negative, summing to 1: the query's central projection on the chord triangle.
    """
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    points = np.ascontiguousarray(points, dtype=np.float64)
    queries = np.ascontiguousarray(queries, dtype=np.float64)

    def side_tests(face, q):
        t = points[faces[face]]  # (Q, 3, 3)
        return np.stack(
            [
                np.einsum("ij,ij->i", q, np.cross(t[:, 1], t[:, 2])),
                np.einsum("ij,ij->i", q, np.cross(t[:, 2], t[:, 0])),
                np.einsum("ij,ij->i", q, np.cross(t[:, 0], t[:, 1])),
            ],
            axis=1,
        )

    from scipy.spatial import cKDTree

    neighbours = _neighbours(faces)
    most_steps = 4 * int(np.sqrt(len(faces))) + 10
    current = _walk(faces, points, neighbours, queries, np.full(len(queries), -1), most_steps)
    lost = np.flatnonzero(current < 0)
    if lost.size:
        vertex_face = np.empty(len(points), dtype=np.int64)
        vertex_face[faces.ravel()] = np.repeat(np.arange(len(faces)), 3)
        starts = vertex_face[cKDTree(points).query(queries[lost])[1]]
        current[lost] = _walk(faces, points, neighbours, queries[lost], starts, most_steps)
    for index in np.flatnonzero(current < 0):  # queries the walk did not bring home
        tests = side_tests(np.arange(len(faces)), np.broadcast_to(queries[index], (len(faces), 3)))
        current[index] = np.argmax(tests.min(axis=1))
    weights = np.clip(side_tests(current, queries), 0.0, None)
    weights /= np.maximum(weights.sum(axis=1, keepdims=True), 1e-300)
    return current, weights


def sample(
    vertices: np.ndarray, faces: np.ndarray, points: np.ndarray, size: int, normals: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray | None]:
    """Sample the mesh positions (and normals) on the octahedral grid.

    Parameters
    ----------
    vertices : ndarray of float, shape (V, 3)
        Mesh positions (any unit).
    faces : ndarray of int, shape (F, 3)
    points : ndarray of float, shape (V, 3)
        The spherical parameterization (unit vectors).
    size : int
        Side ``n`` of the image.
    normals : ndarray of float, shape (V, 3), optional
        Vertex normals to interpolate.

    Returns
    -------
    image : ndarray of float, shape (n, n, 3)
        Positions, in the mesh's unit.
    normal_map : ndarray of float, shape (n, n, 3), or None
        Unit normals interpolated at the same points.
    """
    queries = octahedral.square_to_sphere(octahedral.grid(size)).reshape(-1, 3)
    face, weights = locate(faces, points, queries)
    corners = faces[face]
    image = np.einsum("qk,qkc->qc", weights, vertices[corners]).reshape(size, size, 3)
    if normals is None:
        return image, None
    normal_map = np.einsum("qk,qkc->qc", weights, normals[corners])
    normal_map /= np.maximum(np.linalg.norm(normal_map, axis=1, keepdims=True), 1e-300)
    return image, normal_map.reshape(size, size, 3)


def triangulation(size: int) -> np.ndarray:
    """Faces of the closed mesh on the pixels of a ``size`` x ``size`` geometry image.

    Vertex ``i * size + j`` is pixel ``(i, j)``. Interior squares are split along the
    octahedron's edges (the diagonals of the four quadrants); the border squares close the
    fold of each edge; two triangles join the four corners around the south pole. Faces turn
    counterclockwise seen from outside.

    Returns
    -------
    ndarray of int, shape (2 size^2 - 4, 3)
    """
    if size < 4 or size % 2:
        raise ValueError(f"a geometry image needs an even side of at least 4, got {size}")
    n = size
    index = np.arange(n * n).reshape(n, n)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a, b, c, d = index[i, j], index[i, j + 1], index[i + 1, j + 1], index[i + 1, j]
    # The octahedron's edges run along (1, 1) where u v < 0 and along (1, -1) where u v > 0.
    along_main = ((2 * i + 2 - n) * (2 * j + 2 - n) <= 0).ravel()
    a, b, c, d = a.ravel(), b.ravel(), c.ravel(), d.ravel()
    interior = np.concatenate(
        [
            np.where(along_main[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1)),
            np.where(along_main[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1)),
        ]
    )
    # Fold of each edge: the border row or column, and itself reversed, bound a strip of
    # squares (k, k+1, n-2-k, n-1-k) for k < n/2 - 1.
    k = np.arange(n // 2 - 1)
    strips = []
    for line in (index[0, :], index[:, -1], index[-1, ::-1], index[::-1, 0]):  # clockwise in the image
        p, q, r, s = line[k], line[k + 1], line[n - 2 - k], line[n - 1 - k]
        strips += [np.stack([p, s, r], 1), np.stack([p, r, q], 1)]
    corners = np.array(
        [[index[0, 0], index[-1, 0], index[-1, -1]], [index[0, 0], index[-1, -1], index[0, -1]]]
    )
    return np.concatenate([interior, *strips, corners]).astype(np.int64)


def mesh_from_image(image: np.ndarray):
    """The closed mesh of a geometry image.

    Parameters
    ----------
    image : ndarray of float, shape (n, n, 3)
        Positions; ``n`` even.

    Returns
    -------
    trimesh.Trimesh
        ``n^2`` vertices and ``2 n^2 - 4`` faces (closed, genus 0, nothing merged).
    """
    import trimesh

    image = np.asarray(image, dtype=np.float64)
    if image.ndim != 3 or image.shape[0] != image.shape[1] or image.shape[2] != 3:
        raise ValueError(f"a geometry image is a square n x n x 3 array, got shape {image.shape}")
    return trimesh.Trimesh(image.reshape(-1, 3), triangulation(image.shape[0]), process=False)


def coarsen(image: np.ndarray, vertices: int, most: int | None = None) -> np.ndarray:
    """Halve a geometry image (mean of each 2 x 2 block) while its halves keep ``vertices`` pixels,
    or while it has more than ``most`` pixels.

    The centre of each 2 x 2 block of the octahedral grid of side ``n`` is the pixel centre of
    the grid of side ``n / 2``, so the mean is the image at half the side, smoothed by one fine
    pixel (on fandisk at 512 x 512, 8 bits per vertex, decimated to its 7,229 vertices: 70.8 dB
    from 512, 69.7 dB from 256, in a fifth of the time).

    Parameters
    ----------
    image : ndarray of float, shape (n, n, 3)
    vertices : int
    most : int, optional
        Most pixels of the result (halving stops at an odd half side even above it).

    Returns
    -------
    ndarray of float, shape (m, m, 3)
        ``m = n / 2**k`` for the largest ``k`` with ``m`` even and ``m^2 >= vertices``, or the
        smallest ``k`` with ``m^2 <= most`` if that is larger.
    """
    most = image.shape[0] ** 2 if most is None else most
    while image.shape[0] % 4 == 0 and ((image.shape[0] // 2) ** 2 >= vertices or image.shape[0] ** 2 > most):
        half = image.shape[0] // 2
        image = image.reshape(half, 2, half, 2, image.shape[2]).mean(axis=(1, 3))
    return image


#: How greedy fast-simplification's passes are (its ``agg``, 7 by default), tried in turn until
#: one reaches the asked vertex count. Its threshold on the quadric error grows as the pass count
#: to the power ``agg``, the faster the greedier: on the mesh scaled to a unit diagonal, 1 reaches
#: a fifth of a grid's vertices (the 55,730-vertex bunny of benchmarks/mesh_pipeline.py from its
#: 512 x 512 grid: 82.38 dB, 7 gives 78.26, MeshLab 82.13), 2 a 36th (fandisk from 512 x 512:
#: 85.83 dB, MeshLab 85.82). Lower stops short; higher folds thin parts (the arm: 5 makes
#: non-manifold edges).
AGGRESSIVENESS = (1.0, 2.0, 3.0)
#: Fewest vertices of a grid that fast-simplification decimates; MeshLab takes smaller ones, where
#: it costs 2 s at most and measured up to 0.36 dB better (screwdriver.off at 8 bits per vertex,
#: from 256 x 256; from 512 x 512 the two were within -0.04 to +0.16 dB on the nine shared closed
#: meshes at 0.5 to 8 bits per vertex, BENCHMARKS.md).
FAST_FROM = 512 * 512
#: Largest share above the asked vertex count at which fast-simplification counts as arrived.
SLACK = 0.02
_FAST_LOCK = threading.Lock()  # fast-simplification keeps the mesh it works on in globals


def decimate(mesh, vertices: int):
    """A closed genus-0 mesh simplified to ``vertices`` vertices by quadric edge collapse.

    Garland and Heckbert's error quadrics to the ``2 vertices - 4`` faces a closed genus-0 mesh of
    ``vertices`` vertices has; from a grid of :data:`FAST_FROM` vertices up, by fast-simplification
    (Fast-Quadric-Mesh-Simplification: greedy
    passes under an error threshold that grows, :data:`AGGRESSIVENESS`), on the mesh scaled to a
    unit diagonal (the threshold is absolute). It checks no topology, so its result is checked: if
    no pass count arrives (within :data:`SLACK`) at a closed genus-0 mesh, MeshLab's quadric edge
    collapse does the work (:func:`decimate_meshlab`: topology preserved, as good, 10 to 17 times
    slower on the grids the decoder decimates).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Closed and of genus 0 (as :func:`mesh_from_image` makes), faces facing out.
    vertices : int
        At least 4; a mesh with no more vertices is returned as it is.

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    ValueError
        If MeshLab's simplified mesh is not closed, manifold and of genus 0 (its topology checks
        should prevent it; the mesh is checked rather than trusted).
    """
    import fast_simplification
    import trimesh

    from .checks import check_genus0

    if vertices < 4:
        raise ValueError(f"a closed mesh has at least 4 vertices, asked for {vertices}")
    if vertices >= len(mesh.vertices):
        return mesh
    if len(mesh.vertices) < FAST_FROM:
        return decimate_meshlab(mesh, vertices)
    points = np.asarray(mesh.vertices, np.float64)
    centre = points.mean(axis=0)
    scale = max(float(np.linalg.norm(np.ptp(points, axis=0))), 1e-300)
    unit, faces = (points - centre) / scale, np.asarray(mesh.faces, np.int32)
    for aggressiveness in AGGRESSIVENESS:
        with _FAST_LOCK:
            out, out_faces = fast_simplification.simplify(
                unit, faces, target_count=2 * vertices - 4, agg=aggressiveness
            )
        if len(out) <= (1.0 + SLACK) * vertices:
            simplified = trimesh.Trimesh(out * scale + centre, out_faces.astype(np.int64), process=False)
            try:
                check_genus0(simplified.vertices, simplified.faces)
                return simplified
            except ValueError:  # a fold or a pinched vertex: greedier passes make more
                break
    return decimate_meshlab(mesh, vertices)


@confined
def decimate_meshlab(mesh, vertices: int):
    """:func:`decimate` by MeshLab's quadric edge collapse (pymeshlab, Garland and Heckbert's error
    quadrics, optimal placement, topology preserved) alone.

    Raises
    ------
    ValueError
        If the simplified mesh is not closed, manifold and of genus 0.
    """
    import pymeshlab
    import trimesh

    from .checks import check_genus0

    if vertices >= len(mesh.vertices):
        return mesh
    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(pymeshlab.Mesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int32)))
    meshset.meshing_decimation_quadric_edge_collapse(
        targetfacenum=2 * vertices - 4, preservetopology=True, optimalplacement=True, autoclean=True
    )
    out = meshset.current_mesh()
    simplified = trimesh.Trimesh(out.vertex_matrix(), out.face_matrix().astype(np.int64), process=False)
    try:
        check_genus0(simplified.vertices, simplified.faces)
    except ValueError as err:
        raise ValueError(f"the decimated mesh is no longer closed genus 0 ({err})") from None
    return simplified
