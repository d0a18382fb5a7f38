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
   (the horse's legs) open slowly and can stay under-sampled after ``max_steps``.
4. **Untangling.** The few triangles that the plane embedding still leaves flipped on the
   sphere (long slivers, whose circumcircle holds more than a hemisphere) get their vertices
   moved to the mean of their neighbours until none is flipped.

Orientation: a triangle ``(q0, q1, q2)`` on the sphere is flipped when
``det[q0, q1, q2] <= 0``, i.e. its chord triangle does not face away from the centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SphereMap", "area_distortion", "flipped", "spherical_parameterization"]

_WEIGHT_FLOOR = 1e-3  # cotangent weights below this fraction of the median are raised to it
_PUNCTURE_INRADIUS = 10.0  # the pinned triangle's size in the plane: its outside is a small polar cap


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


def _untangle(faces: np.ndarray, points: np.ndarray, max_rounds: int = 50) -> np.ndarray:
    """Move the vertices of flipped triangles to the mean of their neighbours, adding the
    vertices of the triangles still flipped each round, until none is (or ``max_rounds``)."""
    from scipy.sparse import coo_matrix

    n = len(points)
    i = faces[:, [0, 1, 2, 1, 2, 0]].ravel()
    j = faces[:, [1, 2, 0, 0, 1, 2]].ravel()
    adjacency = coo_matrix((np.ones(i.size), (i, j)), shape=(n, n)).tocsr()
    adjacency.data[:] = 1.0
    region = np.zeros(n, dtype=bool)
    for _ in range(max_rounds):
        bad = flipped(faces, points)
        if not bad.any():
            break
        region[faces[bad].ravel()] = True
        for _ in range(10):
            mean = adjacency @ points
            points = np.where(region[:, None], mean / np.linalg.norm(mean, axis=1, keepdims=True), points)
    return points


def flipped(faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Boolean mask, shape (F,): triangles whose chord triangle on the sphere faces inwards.

    Parameters
    ----------
    faces : ndarray of int, shape (F, 3)
    points : ndarray of float, shape (V, 3)
        Unit vectors.
    """
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = _corners(faces, points)
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

    This layout (and ``np.take`` rather than fancy indexing) makes the per-face arithmetic
    of the relaxation several times faster than on (F, 3) rows.
    """
    columns = np.ascontiguousarray(points.T)
    return [np.take(columns, np.ascontiguousarray(faces[:, k]), axis=1) for k in range(3)]


class _Dirichlet:
    """Symmetric Dirichlet energy of the map from the mesh triangles to the chord triangles.

    Written out per component rather than as stacks of small matrix products, which numpy
    runs far slower.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        p = vertices[faces]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        length = np.linalg.norm(e1, axis=1)
        x_axis = e1 / length[:, None]
        normal = np.cross(e1, e2)
        y_axis = np.cross(normal / np.linalg.norm(normal, axis=1, keepdims=True), x_axis)
        # In the triangle's own plane the edges are the columns of R = [[l, a], [0, h]], and
        # J = [q1 - q0, q2 - q0] R^-1, with R^-1 = [[1/l, -a/(l h)], [0, 1/h]].
        a = np.einsum("ij,ij->i", e2, x_axis)
        h = np.einsum("ij,ij->i", e2, y_axis)
        self.faces = faces
        self.corner_index = faces.T.ravel()  # corner k of face f at k * F + f
        self.n = len(vertices)
        self.area = 0.5 * length * h
        self.inverse = 1 / length, -a / (length * h), 1 / h

    def jacobian(self, points):
        """Per triangle: the columns j0, j1 of J (3, F), G = J^T J as g00, g01, g11, tr G, det G (F,)."""
        q0, q1, q2 = _corners(self.faces, points)
        e1, e2 = q1 - q0, q2 - q0
        r00, r01, r11 = self.inverse
        j0, j1 = e1 * r00, e1 * r01 + e2 * r11
        g00, g01, g11 = (np.sum(x * y, axis=0) for x, y in ((j0, j0), (j0, j1), (j1, j1)))
        return j0, j1, g00, g01, g11, g00 + g11, g00 * g11 - g01**2

    def energy(self, points: np.ndarray) -> float:
        *_, trace, det = self.jacobian(points)
        if np.any(det <= 0):
            return np.inf
        return float(self.area @ (trace + trace / det))

    def gradient(self, points: np.ndarray) -> np.ndarray:
        j0, j1, g00, g01, g11, trace, det = self.jacobian(points)
        # d(t + t/d)/dJ = 2 J (1 + 1/d) - 2 (t/d^2) J adj(G), adj(G) = [[g11, -g01], [-g01, g00]].
        own, cross = 2 * self.area * (1 + 1 / det), 2 * self.area * trace / det**2
        d0 = own * j0 - cross * (j0 * g11 - j1 * g01)
        d1 = own * j1 - cross * (j1 * g00 - j0 * g01)
        # Back through J = E R^-1: dE = dJ R^-T.
        r00, r01, r11 = self.inverse
        d_e1, d_e2 = d0 * r00 + d1 * r01, d1 * r11
        per_corner = np.concatenate([-d_e1 - d_e2, d_e1, d_e2], axis=1)  # (3, 3F), as corner_index
        return np.column_stack(
            [np.bincount(self.corner_index, per_corner[axis], minlength=self.n) for axis in range(3)]
        )


def _relax(vertices, faces, points, laplacian, masses, max_steps: int, tol: float):
    """Lower the symmetric Dirichlet energy on the sphere; returns (points, steps).

    Steps are preconditioned by the cotangent Laplacian (the Hessian of the Dirichlet part),
    projected to the tangent planes and renormalised to the sphere; a backtracking line search
    takes the longest that lowers the energy enough without flipping a triangle that was not
    flipped.
    """
    from scipy.sparse import diags
    from scipy.sparse.linalg import splu

    energy = _Dirichlet(vertices, faces)
    # Single precision halves the time of the solves, the most of a step; a preconditioner
    # needs no more (the line search checks every step on the true energy).
    solve = splu((2 * (laplacian + diags(1e-3 * masses))).astype(np.float32).tocsc()).solve
    current = energy.energy(points)
    was_flipped = flipped(faces, points)
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
                trial_flipped = flipped(faces, trial)
                if not np.any(trial_flipped & ~was_flipped):
                    break
            step /= 2
        else:
            return points, iteration
        points, was_flipped = trial, trial_flipped
        previous, current = current, value
        if previous - current < tol * current:
            return points, iteration + 1
    return points, max_steps


def spherical_parameterization(
    vertices: np.ndarray, faces: np.ndarray, *, max_steps: int = 300, tol: float = 1e-4
) -> SphereMap:
    """Map a closed genus-0 mesh to the unit sphere, one point per vertex, with no flip.

    Parameters
    ----------
    vertices : ndarray of float, shape (V, 3)
        Positions, any unit; the faces must face outwards.
    faces : ndarray of int, shape (F, 3)
        Triangles of a mesh that passes :func:`bandelets.surfaces.checks.check_genus0`.
    max_steps : int
        Most relaxation steps; 0 keeps the centred conformal map.
    tol : float
        The relaxation stops when a step lowers the energy by less than this fraction.

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
    # Scale the surface to the sphere's area, so that an isometry would fit.
    vertices = (vertices - vertices.mean(axis=0)) * np.sqrt(4 * np.pi / _face_areas(vertices, faces).sum())
    laplacian = _cotangent_laplacian(vertices, faces)
    masses = np.bincount(
        faces.ravel(), np.repeat(_face_areas(vertices, faces) / 3, 3), minlength=len(vertices)
    )
    points = _inverse_stereographic(_plane_map(vertices, faces, laplacian))
    points = _mobius_centre(points, masses)
    steps = 0
    if max_steps:
        points, steps = _relax(vertices, faces, points, laplacian, masses, max_steps, tol)
    points = _untangle(faces, points)
    distortion = area_distortion(vertices, faces, points)
    if distortion["flips"]:
        raise ValueError(
            f"spherical parameterization flipped {distortion['flips']} triangles "
            "(degenerate or needle triangles in the mesh?)"
        )
    return SphereMap(points, distortion, steps)
