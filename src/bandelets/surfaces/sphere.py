"""Spherical parameterization of a closed genus-0 triangle mesh, with no flipped triangle.

Coarse to fine, after Praun and Hoppe (2003): the mesh is decimated in nested levels of about
a quarter of the vertices each, down to about 100 (:mod:`.hierarchy`, pymeshlab's quadric
edge collapse); the coarsest level is mapped as below, and each finer level starts from its
vertices placed on the coarser level's map (closest point on the coarser surface), then is
untangled and relaxed. A limb that is a few triangles on the coarsest level opens there in a
few hundred cheap steps, and stays open on the finer levels: on the arm (8,311 vertices), the
one-level map left the hand crushed to 1e-8 of its share of the sphere (uncoded geometry image
18.7 dB at 256^2), the coarse-to-fine one spreads it (76 dB). If a level's placement cannot be
untangled, the mesh is mapped in one level (``coarsest=None``).

On one level:

1. **Conformal start** (coarsest level only). One triangle (the largest) is punctured and
   pinned, with its own shape, as the boundary of a plane domain; the other vertices solve a
   sparse cotangent Laplace equation (a discrete harmonic, hence nearly conformal, map). The
   cotangent weights are floored at a small positive value, so Tutte's theorem makes the plane
   map an embedding. The inverse stereographic projection carries it to the unit sphere.
2. **Mobius centring.** Maps of the ball that move the area-weighted centroid of the
   vertices to the centre, until it stays there: the area the conformal map crushes is
   shared out between the extremities instead of piling up at one of them.
3. **Untangling.** The triangles flipped on the sphere (long slivers of the conformal start,
   folds of a placement) get their vertices moved to the mean of their neighbours until none
   is; the relaxation needs a flip-free start.
4. **Relaxation.** The energy ``sum_f A_f (w tr G + tr G / det G) / c_f`` of the map from
   each mesh triangle (area ``A_f``, surface scaled to the sphere's area) to its chord
   triangle on the sphere: ``tr G / det G = 1/s1^2 + 1/s2^2`` is the squared L2 geometric
   stretch of Sander et al. (2001) of the inverse map (sphere to surface), which Praun and
   Hoppe minimise so that no part of the surface is undersampled; ``w tr G`` (``w = 1``: the
   symmetric Dirichlet energy) keeps triangles from growing without bound; ``c_f``, the chord
   plane's distance to the centre (1 for small triangles), is a barrier that makes the energy
   infinite at a flip, so a step may not flip a triangle. It is lowered by steps
   preconditioned with the cotangent Laplacian, projected to the tangent planes and
   renormalised to the sphere, under a backtracking line search; the relaxation stops when ten
   steps in a row gained little, or after a number of steps that bounds the time.
5. **Untangling** again, in case.

Written here: the energy, its gradient and the relaxation (numba loops; no library minimises a
stretch energy of a sphere map: libigl's SLIM and ARAP parameterize onto the plane), the
conformal start (a scipy sparse solve), the closest-point placement (:mod:`.hierarchy`) and the
untangling's 3-variable linear programs (:mod:`.smalllp`, compiled: scipy's ``linprog`` costs
5 ms a call, and fandisk's untangling makes 35,970). The decimation is pymeshlab's.

Orientation: a triangle ``(q0, q1, q2)`` on the sphere is flipped when
``det[q0, q1, q2] <= 0``, i.e. its chord triangle does not face away from the centre. It is
computed from the edge vectors, ``q0 . ((q1 - q0) x (q2 - q0))``: the conformal start crushes
long limbs (a screwdriver's shaft) to triangles 1e-10 across, whose determinant taken from the
whole unit vectors is rounding noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .hierarchy import levels, place
from .smalllp import OPTIMAL, maximize
from .stretch import area_distortion, face_areas, flipped, relax

__all__ = ["SphereMap", "spherical_parameterization"]

_WEIGHT_FLOOR = 1e-3  # cotangent weights below this fraction of the median are raised to it
_PUNCTURE_INRADIUS = 10.0  # the pinned triangle's size in the plane: its outside is a small polar cap
_WORK = 2e6  # default most relaxation steps times vertices, on each level
# Most steps on the coarsest level of a hierarchy (a few hundred vertices, about 0.3 ms a step):
# its conformal start crushes limbs to 1e-10 of their share, and opening them all may take
# many steps. The cow's 172-vertex base needs 12,084 (stretch 1.92); capped at 3,000 it kept
# a stretch of 1,215, which the finer levels could not undo (20 % of the cow's area crushed,
# uncoded 256^2 geometry image 38.7 dB).
_BASE_STEPS = 50_000
# Bases of the next tries, when a level of a try could not be untangled (the arm succeeds from
# 50 vertices, the horse from 400; which one fails is a matter of a few triangles).
_RETRY_BASES = (50, 400)
_SINGLE_WORK = 1.5e7  # most steps times vertices when the mesh is mapped in one level: about 20 s
_COARSEST = 100  # vertices of the coarsest level of the hierarchy
_CONFORMAL_WEIGHT = 1.0  # weight of tr G beside the stretch term tr G / det G
# Least depth of a 1-ring's kernel point that counts as unflipping the ring: a ring whose
# kernel is a point or a segment (crushed corners) has a depth of 0 up to rounding (1e-16 to
# 1e-15), either sign. Moving the vertices whose depth came out at +1e-16 (HiGHS reported 0)
# lowered fandisk's uncoded 256^2 ceiling from 77.0 to 74.1 dB (stretch 1.18 to 1.76).
_DEPTH = 1e-14


@dataclass(frozen=True)
class SphereMap:
    """A spherical parameterization and what it cost.

    Attributes
    ----------
    points : ndarray of float, shape (V, 3)
        Unit vectors, one per mesh vertex.
    distortion : dict
        :func:`area_distortion` of the map (``flips`` is 0).
    iterations : int
        Relaxation steps taken, over all levels.
    levels : int
        Levels of the coarse-to-fine hierarchy mapped (1: the mesh alone).
    """

    points: np.ndarray
    distortion: dict
    iterations: int
    levels: int = 1


def _cotangents(vertices: np.ndarray, faces: np.ndarray):
    """Half cotangent weights of the edges, both directions, floored at a small positive value.

    Returns rows, cols (int, shape (6F,)) and weights (float, shape (6F,)); summing duplicates
    gives the usual ``w_ij = (cot alpha + cot beta) / 2``. With positive weights, Tutte's
    theorem makes the harmonic plane map an embedding.
    """
    p = vertices[faces]
    rows, cols, weights = [], [], []
    for k in range(3):
        a, b = (k + 1) % 3, (k + 2) % 3
        u, v = p[:, a] - p[:, k], p[:, b] - p[:, k]
        cot = np.einsum("ij,ij->i", u, v) / np.maximum(np.linalg.norm(np.cross(u, v), axis=1), 1e-300)
        rows.append(faces[:, a])
        cols.append(faces[:, b])
        weights.append(0.5 * cot)
    weights = np.concatenate(weights * 2)
    weights = np.maximum(weights, _WEIGHT_FLOOR * np.median(np.abs(weights)))
    return np.concatenate(rows + cols), np.concatenate(cols + rows), weights


def _cotangent_laplacian(vertices: np.ndarray, faces: np.ndarray):
    """Sparse symmetric ``L`` with ``L_ij = -w_ij``, ``L_ii = sum_j w_ij``, shape (V, V)."""
    from scipy.sparse import coo_matrix, diags

    n = len(vertices)
    rows, cols, weights = _cotangents(vertices, faces)
    w = coo_matrix((weights, (rows, cols)), shape=(n, n)).tocsr()
    return diags(np.asarray(w.sum(axis=1)).ravel()) - w


def _plane_map(vertices: np.ndarray, faces: np.ndarray, laplacian) -> np.ndarray:
    """Harmonic map of the mesh minus its largest triangle onto that triangle; complex, shape (V,)."""
    from scipy.sparse.linalg import spsolve

    puncture = faces[np.argmax(face_areas(vertices, faces))]
    a, b, c = vertices[puncture]
    x_axis = (b - a) / np.linalg.norm(b - a)
    normal = np.cross(b - a, c - a)
    y_axis = np.cross(normal / np.linalg.norm(normal), x_axis)
    corners = np.array([0.0, (b - a) @ x_axis + 1j * 0.0, (c - a) @ x_axis + 1j * ((c - a) @ y_axis)])
    corners -= corners.mean()
    # Inradius of the triangle = 2 area / perimeter.
    perimeter = np.sum(np.abs(corners - np.roll(corners, 1)))
    area = 0.5 * abs(np.imag(np.conj(corners[1] - corners[0]) * (corners[2] - corners[0])))
    corners *= _PUNCTURE_INRADIUS * perimeter / (2.0 * area)
    interior = np.setdiff1d(np.arange(len(vertices)), puncture)
    lap = laplacian.tocsr()
    rhs = -(lap[interior][:, puncture] @ np.column_stack([corners.real, corners.imag]))
    solution = spsolve(lap[interior][:, interior].tocsc(), rhs)
    z = np.empty(len(vertices), dtype=complex)
    z[puncture] = corners
    z[interior] = solution[:, 0] + 1j * solution[:, 1]
    # The inverse stereographic projection reverses orientation: the faces must turn clockwise,
    # the boundary (the puncture, seen from the other side) counterclockwise.
    return z if np.imag(np.conj(corners[1] - corners[0]) * (corners[2] - corners[0])) > 0 else np.conj(z)


def _inverse_stereographic(z: np.ndarray) -> np.ndarray:
    r2 = np.abs(z) ** 2
    return np.column_stack([2 * z.real, 2 * z.imag, r2 - 1]) / (r2 + 1)[:, None]


def _mobius_centre(points: np.ndarray, masses: np.ndarray, tol: float = 1e-10, max_steps: int = 200):
    """Apply ball automorphisms until the mass-weighted centroid of ``points`` is the origin."""
    w = masses / masses.sum()
    for _ in range(max_steps):
        c = w @ points
        if np.linalg.norm(c) < tol:
            break
        d = points - c
        points = (1 - c @ c) * d / np.einsum("ij,ij->i", d, d)[:, None] - c
        points /= np.linalg.norm(points, axis=1, keepdims=True)
    return points


@njit(cache=True)
def _kernel_point(points, ring_a, ring_b, centre):
    """The point deepest inside the kernel of a vertex's 1-ring on the sphere.

    A triangle ``(x, a, b)`` of the ring is unflipped when ``det[x, a, b] = x . (a x b) > 0``:
    a half-space through the centre, linear in ``x``. In the gnomonic chart tangent at
    ``centre``, ``x = centre + u e1 + v e2``, the linear program ``max t`` subject to
    ``x . n_i >= t`` (``n_i`` the unit ``a x b``), ``|u|, |v| <= 1`` and ``t <= 1`` gives the
    point farthest inside all of them (:func:`.smalllp.maximize`).

    Parameters
    ----------
    points : ndarray of float, shape (V, 3)
    ring_a, ring_b : ndarray of int, shape (R,)
        The other two corners ``(a, b)`` of each triangle around the vertex, in its order.
    centre : ndarray of float, shape (3,)
        Unit vector where the chart touches the sphere.

    Returns
    -------
    point : ndarray of float, shape (3,)
        Unit vector.
    depth : float
        ``t``: positive when the point unflips every triangle of the ring (-inf if the program
        failed).
    """
    axis = np.array([1.0, 0.0, 0.0]) if abs(centre[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(centre, axis)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(centre, e1)
    r = len(ring_a)
    # In (u + 1, v + 1, t), so that a degenerate program (a crushed ring: all of its points are
    # optimal) leaves u and v at their lower bound, as HiGHS does.
    # Rows: -(n.e1) u - (n.e2) v + t <= n.centre for each triangle, then 0 <= u + 1, v + 1 <= 2
    # and t <= 1.
    a = np.zeros((r + 5, 3))
    b = np.ones(r + 5)
    for i in range(r):
        normal = np.cross(points[ring_a[i]], points[ring_b[i]])
        normal /= max(np.linalg.norm(normal), 1e-300)
        a[i, 0] = -(normal @ e1)
        a[i, 1] = -(normal @ e2)
        a[i, 2] = 1.0
        b[i] = normal @ centre + a[i, 0] + a[i, 1]
    a[r, 0], a[r + 1, 0], a[r + 2, 1], a[r + 3, 1], a[r + 4, 2] = 1.0, -1.0, 1.0, -1.0, 1.0
    b[r], b[r + 1], b[r + 2], b[r + 3] = 2.0, 0.0, 2.0, 0.0
    status, x, t = maximize(np.array([0.0, 0.0, 1.0]), a, b)
    if status != OPTIMAL:
        return centre.copy(), -np.inf
    point = centre + (x[0] - 1.0) * e1 + (x[1] - 1.0) * e2
    return point / np.linalg.norm(point), t


@njit(cache=True)
def _untangle_sweep(faces, points, vertices, corner_face, corner, offsets, lenient, stuck):
    """Move each of ``vertices`` in turn (in place) to :func:`_kernel_point` of its 1-ring if
    that unflips the ring (or, when ``lenient``, wherever the program found); mark in ``stuck``
    those whose kernel is empty."""
    for vertex in vertices:
        count = offsets[vertex + 1] - offsets[vertex]
        ring_a = np.empty(count, dtype=np.int64)
        ring_b = np.empty(count, dtype=np.int64)
        centre = np.zeros(3)
        for i in range(count):
            f, k = corner_face[offsets[vertex] + i], corner[offsets[vertex] + i]
            ring_a[i], ring_b[i] = faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
            centre += points[ring_a[i]]
        centre /= max(np.linalg.norm(centre), 1e-300)
        point, depth = _kernel_point(points, ring_a, ring_b, centre)
        # A vertex whose kernel is empty waits for its neighbours, unless a round gained
        # nothing: then it takes the point of least violation.
        if depth > _DEPTH or (lenient and np.isfinite(depth)):
            points[vertex] = point
        stuck[vertex] = depth <= _DEPTH


def _untangle(faces: np.ndarray, points: np.ndarray, max_rounds: int = 30) -> np.ndarray:
    """Move the vertices of flipped triangles, one by one, deepest into the kernel of their
    1-ring (:func:`_kernel_point`, as Praun and Hoppe place an inserted vertex), round after
    round, taking in the neighbours of vertices whose kernel is empty, until none is flipped
    (or ``max_rounds``)."""
    from scipy.sparse import coo_matrix

    n = len(points)
    order = np.argsort(faces.ravel(), kind="stable")
    offsets = np.searchsorted(faces.ravel()[order], np.arange(n + 1))
    corner_face, corner = order // 3, order % 3
    i = faces[:, [0, 1, 2]].ravel()
    j = faces[:, [1, 2, 0]].ravel()
    adjacency = coo_matrix((np.ones(i.size), (i, j)), shape=(n, n)).tocsr()
    points = points.copy()
    bad = flipped(faces, points)
    best, fewest = points.copy(), int(bad.sum())
    stuck = np.zeros(n, dtype=bool)
    lenient = False
    for _ in range(max_rounds):
        if not bad.any():
            break
        todo = np.zeros(n, dtype=bool)
        todo[faces[bad].ravel()] = True
        todo |= (adjacency @ stuck + adjacency.T @ stuck) > 0
        stuck[:] = False
        _untangle_sweep(faces, points, np.flatnonzero(todo), corner_face, corner, offsets, lenient, stuck)
        bad = flipped(faces, points)
        lenient = int(bad.sum()) >= fewest
        if int(bad.sum()) < fewest:
            best, fewest = points.copy(), int(bad.sum())
        elif bad.sum() > 2 * fewest + 10:  # diverging: back to the best state
            points = best.copy()
            bad = flipped(faces, points)
    # The last few: their corners to the mean of their neighbours, which may leave slivers that
    # the relaxation's one-vertex moves then repair.
    symmetric = ((adjacency + adjacency.T) > 0).astype(np.float64)
    points = best.copy()
    for _ in range(max_rounds if fewest else 0):
        bad = flipped(faces, points)
        if not bad.any():
            return points
        region = np.unique(faces[bad].ravel())
        mean = symmetric[region] @ points
        points[region] = mean / np.linalg.norm(mean, axis=1, keepdims=True)
    if flipped(faces, points).sum() < fewest:
        best, fewest = points, int(flipped(faces, points).sum())
    # Last resort: smooth a region that grows round after round around them.
    region = np.zeros(n, dtype=bool)
    points = best.copy()
    for _ in range(max_rounds if fewest else 0):
        bad = flipped(faces, points)
        if not bad.any():
            return points
        region[faces[bad].ravel()] = True
        for _ in range(10):
            mean = symmetric @ points
            points = np.where(region[:, None], mean / np.linalg.norm(mean, axis=1, keepdims=True), points)
    return points if flipped(faces, points).sum() < fewest else best


def _map_level(vertices, faces, start, max_steps, tol, weight):
    """Map one level: from ``start`` (unit vectors, (V, 3)) or, if None, the centred conformal
    map; untangled, relaxed and untangled again. Returns (points, steps)."""
    # Scale the surface to the sphere's area, so that an isometry would fit.
    vertices = (vertices - vertices.mean(axis=0)) * np.sqrt(4 * np.pi / face_areas(vertices, faces).sum())
    laplacian = _cotangent_laplacian(vertices, faces)
    masses = np.bincount(
        faces.ravel(), np.repeat(face_areas(vertices, faces) / 3, 3), minlength=len(vertices)
    )
    if start is None:
        start = _mobius_centre(_inverse_stereographic(_plane_map(vertices, faces, laplacian)), masses)
    # A flipped triangle locks its neighbours (no step may flip another), so none is left.
    points = _untangle(faces, start)
    steps = 0
    if max_steps is None:
        max_steps = int(np.clip(_WORK / len(vertices), 30, 3000))
    if max_steps:
        points, steps = relax(vertices, faces, points, laplacian, masses, max_steps, tol, weight)
    return _untangle(faces, points), steps


def spherical_parameterization(
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    max_steps: int | None = None,
    tol: float = 1e-4,
    coarsest: int | None = _COARSEST,
    weight: float = _CONFORMAL_WEIGHT,
    tried: tuple = (),
) -> SphereMap:
    """Map a closed genus-0 mesh to the unit sphere, one point per vertex, with no flip.

    Parameters
    ----------
    vertices : ndarray of float, shape (V, 3)
        Positions, any unit; the faces must face outwards.
    faces : ndarray of int, shape (F, 3)
        Triangles of a mesh that passes :func:`bandelets.surfaces.checks.check_genus0`.
    max_steps : int, optional
        Most relaxation steps on each level; 0 keeps the centred conformal map (of the
        coarsest level, carried to the others). Default: 50,000 on the coarsest level of a
        hierarchy; on the others 2 million vertex-steps, from 30 to 3000 steps (a mesh mapped
        in one level: 15 million, from 100 to 3000), so that the time stays bounded.
    tol : float
        The relaxation of a level stops when its last 10 steps lowered the energy by less than
        this fraction each on average.
    coarsest : int or None
        Vertices of the coarsest level of the hierarchy; None maps the mesh in one level.
    weight : float
        Weight of the conformal (Dirichlet) term ``tr G`` beside the stretch term
        ``tr G / det G`` of the energy.
    tried : tuple of int
        Bases already tried (internal: a level that cannot be untangled makes it try the
        next base of ``_RETRY_BASES``, then one level).

    Returns
    -------
    SphereMap

    Raises
    ------
    ValueError
        If a triangle is still flipped (degenerate input triangles).
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    hierarchy = [(np.arange(len(vertices)), faces)]
    if coarsest is not None:
        hierarchy = levels(vertices, faces, coarsest)
    points = np.zeros_like(vertices)
    start, total = None, 0
    for depth in range(len(hierarchy) - 1, -1, -1):
        kept, level_faces = hierarchy[depth]
        cap = _BASE_STEPS if max_steps is None and depth == len(hierarchy) - 1 > 0 else max_steps
        level_points, steps = _map_level(vertices[kept], level_faces, start, cap, tol, weight)
        total += steps
        points[kept] = level_points
        if depth:
            finer, finer_faces = hierarchy[depth - 1]
            start = place(vertices[finer], vertices[kept], level_faces, level_points)
            start[np.searchsorted(finer, kept)] = level_points  # the coarse vertices stay put
    distortion = area_distortion(vertices, faces, points)
    if distortion["flips"] and len(hierarchy) > 1:
        # Untangling a placement failed on some level (a few triangles): a hierarchy with
        # another base, else the mesh in one level, with the one-level budget.
        later = [n for n in _RETRY_BASES if n not in (*tried, coarsest) and 2 * n < len(vertices)]
        if later:
            retry = {"coarsest": later[0], "max_steps": max_steps, "tried": (*tried, coarsest)}
        else:
            single = int(np.clip(_SINGLE_WORK / len(vertices), 100, 3000))
            retry = {"coarsest": None, "max_steps": single if max_steps is None else max_steps}
        return spherical_parameterization(vertices, faces, tol=tol, weight=weight, **retry)
    if distortion["flips"]:
        raise ValueError(
            f"spherical parameterization flipped {distortion['flips']} triangles "
            "(degenerate or needle triangles in the mesh?)"
        )
    return SphereMap(points, distortion, total, len(hierarchy))
