"""Spherical parameterization of a closed genus-0 triangle mesh, with no flipped triangle.

Three steps:

1. **Conformal start.** One triangle (the largest) is punctured and pinned, with its own
   shape, as the boundary of a plane domain; the other vertices solve a sparse cotangent
   Laplace equation (a discrete harmonic, hence nearly conformal, map). The cotangent weights
   are floored at a small positive value, so Tutte's theorem makes the plane map an
   embedding. The inverse stereographic projection carries it to the unit sphere.
2. **Mobius centring.** Maps of the ball that move the area-weighted centroid of the
   vertices to the centre, until it stays there: the area the conformal map crushes is
   shared out between the extremities instead of piling up at one of them, whichever
   triangle was punctured.
3. **Relaxation.** The symmetric Dirichlet energy ``sum_f A_f (|J|^2 + |J^-1|^2)`` of the
   map from each mesh triangle (area ``A_f``, surface scaled to the sphere's area) to its
   chord triangle on the sphere is lowered by steps preconditioned with the cotangent
   Laplacian, each projected to the tangent planes and renormalised to the sphere, under a
   backtracking line search that refuses any step flipping a triangle not already flipped.
   The energy is infinite for degenerate triangles and least for an isometry, so it spreads
   out the area that a conformal map concentrates. Limbs crushed by many orders of magnitude
   (the horse's legs) open slowly, over a thousand steps or so, while single steps may gain
   little: the relaxation stops when ten steps in a row gained little. On large meshes the
   default number of steps is capped, so that legs may stay under-sampled there.
4. **Untangling.** The few triangles that the plane embedding still leaves flipped on the
   sphere (long slivers, whose circumcircle holds more than a hemisphere) get their vertices
   moved to the mean of their neighbours until none is flipped.

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

__all__ = ["SphereMap", "area_distortion", "flipped", "spherical_parameterization"]

_WEIGHT_FLOOR = 1e-3  # cotangent weights below this fraction of the median are raised to it
_PUNCTURE_INRADIUS = 10.0  # the pinned triangle's size in the plane: its outside is a small polar cap
_WINDOW = 10  # the relaxation stops when its last this many steps gained too little
_WORK = 1.5e7  # default most relaxation steps times vertices: about 20 s on the 2-core machine
_COARSEST = 100  # vertices of the coarsest level of the hierarchy
_CONFORMAL_WEIGHT = 1.0  # weight of tr G beside the stretch term tr G / det G


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
        Relaxation steps taken.
    """

    points: np.ndarray
    distortion: dict
    iterations: int


def _face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    p = vertices[faces]
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


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

    puncture = faces[np.argmax(_face_areas(vertices, faces))]
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


def _untangle(faces: np.ndarray, points: np.ndarray, laplacian, max_rounds: int = 200) -> np.ndarray:
    """Move the vertices of flipped triangles to the weighted mean of their neighbours, round
    after round, until none is flipped (or ``max_rounds``)."""
    weights = -laplacian.tocsr()
    weights.setdiag(0)
    weights.eliminate_zeros()
    for _ in range(max_rounds):
        bad = flipped(faces, points)
        if not bad.any():
            break
        region = np.unique(faces[bad].ravel())
        mean = weights[region] @ points
        points = points.copy()
        points[region] = mean / np.linalg.norm(mean, axis=1, keepdims=True)
    return points


def flipped(faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Boolean mask, shape (F,): triangles whose chord triangle on the sphere faces inwards.

    Parameters
    ----------
    faces : ndarray of int, shape (F, 3)
    points : ndarray of float, shape (V, 3)
        Unit vectors.
    """
    q0, q1, q2 = _corners(faces, points)
    # det[q0, q1, q2] = q0 . ((q1 - q0) x (q2 - q0)): the products of whole coordinates in
    # q0 . (q1 x q2) cancel down to the triangle's size, and for the triangles that a conformal
    # map crushes to 1e-10 across, their rounding (1e-16) outweighs the result; edge vectors
    # keep it to relative rounding.
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = q0, q1 - q0, q2 - q0
    return x0 * (y1 * z2 - z1 * y2) + y0 * (z1 * x2 - x1 * z2) + z0 * (x1 * y2 - y1 * x2) <= 0


def area_distortion(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> dict:
    """How unevenly the sphere map spreads the surface's area.

    The ratio of a triangle is its share of the sphere's (chord) area over its share of the
    mesh's area: 1 everywhere for an area-preserving map.

    Parameters
    ----------
    vertices : ndarray of float, shape (V, 3)
        Mesh positions.
    faces : ndarray of int, shape (F, 3)
    points : ndarray of float, shape (V, 3)
        The unit vectors of the map.

    Returns
    -------
    dict
        ``mean_abs_log2``: mean of ``|log2 ratio|`` weighted by mesh area; ``p01``, ``p99``:
        1st and 99th percentiles of the ratio over the mesh area; ``min``, ``max``: its
        extremes; ``flips``: number of flipped triangles.
    """
    mesh_share = _face_areas(vertices, faces)
    mesh_share /= mesh_share.sum()
    sphere_share = _face_areas(points, faces)
    sphere_share /= sphere_share.sum()
    ratio = np.maximum(sphere_share, 1e-300) / np.maximum(mesh_share, 1e-300)
    order = np.argsort(ratio)
    cumulative = np.cumsum(mesh_share[order])
    p01, p99 = ratio[order][np.searchsorted(cumulative, [0.01, 0.99]).clip(0, ratio.size - 1)]
    return {
        "mean_abs_log2": float(mesh_share @ np.abs(np.log2(ratio))),
        "p01": float(p01),
        "p99": float(p99),
        "min": float(ratio.min()),
        "max": float(ratio.max()),
        "flips": int(np.sum(flipped(faces, points))),
    }


def _corners(faces: np.ndarray, points: np.ndarray) -> list[np.ndarray]:
    """The three corners of every face, each as (3, F) coordinates first.

    This layout (and ``np.take`` rather than fancy indexing) makes :func:`flipped` several
    times faster than on (F, 3) rows.
    """
    columns = np.ascontiguousarray(points.T)
    return [np.take(columns, np.ascontiguousarray(faces[:, k]), axis=1) for k in range(3)]


@njit(cache=True)
def _chord(points, a, e1, e2):
    """Normal ``n = e1 x e2`` of a chord triangle from its edges ``e1 = q1 - q0``, ``e2``, and
    ``det[q0, q1, q2] = q0 . n``.

    The usual ``g00 g11 - g01^2`` and ``q0 . (q1 x q2)`` lose all their digits to cancellation
    on the triangles a conformal map crushes (areas down to 1e-20 and less); ``det G`` is
    ``(r00 r11)^2 |n|^2``, as ``j0 x j1 = r00 r11 n``.
    """
    n = np.empty(3)
    n[0] = e1[1] * e2[2] - e1[2] * e2[1]
    n[1] = e1[2] * e2[0] - e1[0] * e2[2]
    n[2] = e1[0] * e2[1] - e1[1] * e2[0]
    return n, points[a, 0] * n[0] + points[a, 1] * n[1] + points[a, 2] * n[2]


@njit(cache=True)
def _dirichlet_energy(faces, points, inverse, area, weight):
    """Energy of the map; infinite when a chord triangle is degenerate or flipped.

    ``inverse`` (F, 3) holds ``1/l, -a/(l h), 1/h``, the entries of ``R^-1`` (see
    :class:`_Dirichlet`).
    """
    total = 0.0
    e1 = np.empty(3)
    e2 = np.empty(3)
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        r00, r01, r11 = inverse[f, 0], inverse[f, 1], inverse[f, 2]
        g00 = g11 = 0.0
        for k in range(3):
            e1[k] = points[b, k] - points[a, k]
            e2[k] = points[c, k] - points[a, k]
            j0, j1 = e1[k] * r00, e1[k] * r01 + e2[k] * r11
            g00 += j0 * j0
            g11 += j1 * j1
        n, orientation = _chord(points, a, e1, e2)
        norm2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2]
        det = (r00 * r11) ** 2 * norm2
        if det <= 0.0 or orientation <= 0.0:
            return np.inf
        # c = orientation / |n|: the chord plane's distance to the centre, 1 for a small triangle.
        total += area[f] * (g00 + g11) * (weight + 1.0 / det) * np.sqrt(norm2) / orientation
    return total


@njit(cache=True)
def _dirichlet_gradient(faces, points, inverse, area, weight):
    """Gradient of :func:`_dirichlet_energy` with respect to ``points``, shape (V, 3)."""
    grad = np.zeros(points.shape)
    j0 = np.empty(3)
    j1 = np.empty(3)
    e1 = np.empty(3)
    e2 = np.empty(3)
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        r00, r01, r11 = inverse[f, 0], inverse[f, 1], inverse[f, 2]
        g00 = g01 = g11 = 0.0
        for k in range(3):
            e1[k] = points[b, k] - points[a, k]
            e2[k] = points[c, k] - points[a, k]
            j0[k], j1[k] = e1[k] * r00, e1[k] * r01 + e2[k] * r11
            g00 += j0[k] * j0[k]
            g01 += j0[k] * j1[k]
            g11 += j1[k] * j1[k]
        n, orientation = _chord(points, a, e1, e2)
        norm = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        det = (r00 * r11 * norm) ** 2
        trace = g00 + g11
        barrier = norm / orientation  # 1 / c
        term = area[f] * trace * (weight + 1.0 / det)
        # d(t w + t/d)/dJ = 2 J (w + 1/d) - 2 (t/d^2) J adj(G), adj(G) = [[g11, -g01], [-g01, g00]];
        # then back through J = E R^-1: dE = dJ R^-T; all times the barrier 1/c.
        own = 2.0 * area[f] * (weight + 1.0 / det) * barrier
        cross = 2.0 * area[f] * trace / (det * det) * barrier
        for k in range(3):
            d0 = own * j0[k] - cross * (j0[k] * g11 - j1[k] * g01)
            d1 = own * j1[k] - cross * (j1[k] * g00 - j0[k] * g01)
            d_e1, d_e2 = d0 * r00 + d1 * r01, d1 * r11
            grad[a, k] -= d_e1 + d_e2
            grad[b, k] += d_e1
            grad[c, k] += d_e2
        # term * d(|n| / o): d|n| = (de1 . (e2 x n) + de2 . (n x e1)) / |n|, and
        # do = q0 . dn + dq0 . n = dq0 . (q1 x q2) + dq1 . (q2 x q0) + dq2 . (q0 x q1).
        s_norm = term / (orientation * norm)
        s_orient = -term * norm / (orientation * orientation)
        for k in range(3):
            k1, k2 = (k + 1) % 3, (k + 2) % 3
            d_e1 = s_norm * (e2[k1] * n[k2] - e2[k2] * n[k1])
            d_e2 = s_norm * (n[k1] * e1[k2] - n[k2] * e1[k1])
            grad[a, k] -= d_e1 + d_e2
            grad[b, k] += d_e1
            grad[c, k] += d_e2
            grad[a, k] += s_orient * (points[b, k1] * points[c, k2] - points[b, k2] * points[c, k1])
            grad[b, k] += s_orient * (points[c, k1] * points[a, k2] - points[c, k2] * points[a, k1])
            grad[c, k] += s_orient * (points[a, k1] * points[b, k2] - points[a, k2] * points[b, k1])
    return grad


class _Dirichlet:
    """Symmetric Dirichlet energy of the map from the mesh triangles to the chord triangles.

    In the triangle's own plane its edges are the columns of ``R = [[l, a], [0, h]]``, and the
    Jacobian is ``J = [q1 - q0, q2 - q0] R^-1`` with ``R^-1 = [[1/l, -a/(l h)], [0, 1/h]]``;
    the energy is ``sum_f A_f (tr G + tr G / det G)``, ``G = J^T J``. Numba loops over the
    faces, since a step of the relaxation evaluates it several times.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, weight: float = 1.0):
        self.weight = float(weight)
        p = vertices[faces]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        length = np.linalg.norm(e1, axis=1)
        x_axis = e1 / length[:, None]
        normal = np.cross(e1, e2)
        y_axis = np.cross(normal / np.linalg.norm(normal, axis=1, keepdims=True), x_axis)
        a = np.einsum("ij,ij->i", e2, x_axis)
        h = np.einsum("ij,ij->i", e2, y_axis)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.area = 0.5 * length * h
        self.inverse = np.column_stack([1 / length, -a / (length * h), 1 / h])

    def energy(self, points: np.ndarray) -> float:
        """The energy; infinite if a triangle is flipped or degenerate."""
        return _dirichlet_energy(self.faces, points, self.inverse, self.area, self.weight)

    def gradient(self, points: np.ndarray) -> np.ndarray:
        return _dirichlet_gradient(self.faces, points, self.inverse, self.area, self.weight)


def _relax(vertices, faces, points, laplacian, masses, max_steps: int, tol: float, weight: float = 1.0):
    """Lower the symmetric Dirichlet energy on the sphere; returns (points, steps).

    Steps are preconditioned by the cotangent Laplacian (the Hessian of the Dirichlet part),
    projected to the tangent planes and renormalised to the sphere; a backtracking line search
    takes the longest that lowers the energy enough (the energy is infinite when a triangle
    flips). A start with a flipped triangle is returned as it is.
    """
    from scipy.sparse import diags
    from scipy.sparse.linalg import splu

    energy = _Dirichlet(vertices, faces, weight)
    # Single precision halves the time of the solves, the most of a step; a preconditioner
    # needs no more (the line search checks every step on the true energy).
    solve = splu((2 * (laplacian + diags(1e-3 * masses))).astype(np.float32).tocsc()).solve
    current = energy.energy(points)
    if not np.isfinite(current):
        return points, 0
    history = [current]
    step = 1.0
    for iteration in range(max_steps):
        grad = energy.gradient(points)
        grad -= np.einsum("ij,ij->i", grad, points)[:, None] * points
        direction = -solve(grad.astype(np.float32)).astype(np.float64)
        direction -= np.einsum("ij,ij->i", direction, points)[:, None] * points
        slope = float(np.sum(grad * direction))
        if slope >= 0:
            break
        # Never move a vertex by more than a quarter radian in one step.
        step = min(2 * step, 1.0, 0.25 / max(np.abs(direction).max(), 1e-300))
        for _ in range(60):
            trial = points + step * direction
            trial /= np.linalg.norm(trial, axis=1, keepdims=True)
            value = energy.energy(trial)
            if value <= current + 1e-4 * step * slope:
                break
            step /= 2
        else:
            return points, iteration
        points, current = trial, value
        history.append(current)
        # Over several steps, as single steps may gain little while a limb is still opening.
        if len(history) > _WINDOW and history[-1 - _WINDOW] - current < _WINDOW * tol * current:
            return points, iteration + 1
    return points, max_steps


def _map_level(vertices, faces, start, max_steps, tol, weight):
    """Map one level: from ``start`` (unit vectors, (V, 3)) or, if None, the centred conformal
    map; untangled, relaxed and untangled again. Returns (points, steps)."""
    # Scale the surface to the sphere's area, so that an isometry would fit.
    vertices = (vertices - vertices.mean(axis=0)) * np.sqrt(4 * np.pi / _face_areas(vertices, faces).sum())
    laplacian = _cotangent_laplacian(vertices, faces)
    masses = np.bincount(
        faces.ravel(), np.repeat(_face_areas(vertices, faces) / 3, 3), minlength=len(vertices)
    )
    if start is None:
        start = _mobius_centre(_inverse_stereographic(_plane_map(vertices, faces, laplacian)), masses)
    # A flipped triangle locks its neighbours (no step may flip another), so none is left.
    points = _untangle(faces, start, laplacian)
    steps = 0
    if max_steps is None:
        max_steps = int(np.clip(_WORK / len(vertices), 100, 3000))
    if max_steps:
        points, steps = _relax(vertices, faces, points, laplacian, masses, max_steps, tol, weight)
    return _untangle(faces, points, laplacian), steps


def spherical_parameterization(
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    max_steps: int | None = None,
    tol: float = 1e-4,
    coarsest: int | None = _COARSEST,
    weight: float = _CONFORMAL_WEIGHT,
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
        coarsest level, carried to the others). Default: 3000, fewer on levels of more than
        5,000 vertices (15 million vertex-steps), so that the time stays bounded.
    tol : float
        The relaxation of a level stops when its last 10 steps lowered the energy by less than
        this fraction each on average.
    coarsest : int or None
        Vertices of the coarsest level of the hierarchy; None maps the mesh in one level.
    weight : float
        Weight of the conformal (Dirichlet) term ``tr G`` beside the stretch term
        ``tr G / det G`` of the energy.

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
        level_points, steps = _map_level(vertices[kept], level_faces, start, max_steps, tol, weight)
        total += steps
        points[kept] = level_points
        if depth:
            finer, finer_faces = hierarchy[depth - 1]
            start = place(vertices[finer], vertices[kept], level_faces, level_points)
            start[np.searchsorted(finer, kept)] = level_points  # the coarse vertices stay put
    distortion = area_distortion(vertices, faces, points)
    if distortion["flips"]:
        raise ValueError(
            f"spherical parameterization flipped {distortion['flips']} triangles "
            "(degenerate or needle triangles in the mesh?)"
        )
    return SphereMap(points, distortion, total)
