"""The stretch energy of a map from a mesh to the unit sphere and its relaxation (step 4 of
:mod:`.sphere`): the energy ``sum_f A_f (w tr G + tr G / det G) / c_f`` of every triangle, its
gradient, the preconditioned steps under a backtracking line search, and the measures of a map
(:func:`flipped` triangles, :func:`area_distortion`).

Written here: no library minimises a stretch energy of a sphere map (libigl's SLIM and ARAP
parameterize onto the plane); numba loops over the triangles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["Dirichlet", "area_distortion", "face_areas", "flipped", "relax"]

_WINDOW = 10  # the relaxation stops when its last this many steps gained too little


def _corners(faces: np.ndarray, points: np.ndarray) -> list[np.ndarray]:
    """The three corners of every face, each as (3, F) coordinates first.

    This layout (and ``np.take`` rather than fancy indexing) makes :func:`flipped` several
    times faster than on (F, 3) rows.
    """
    columns = np.ascontiguousarray(points.T)
    return [np.take(columns, np.ascontiguousarray(faces[:, k]), axis=1) for k in range(3)]


@njit(cache=True, inline="always")
def _face_parts(points, a, b, c, r00, r01, r11):
    """Edges ``e1 = q1 - q0``, ``e2``, Jacobian columns ``j0, j1``, normal ``n = e1 x e2`` and
    ``det[q0, q1, q2] = q0 . n`` of a chord triangle, as scalars (no allocation in the loops).

    The usual ``g00 g11 - g01^2`` and ``q0 . (q1 x q2)`` lose all their digits to cancellation
    on the triangles a conformal map crushes (areas down to 1e-20 and less); ``det G`` is
    ``(r00 r11)^2 |n|^2``, as ``j0 x j1 = r00 r11 n``.
    """
    e1x, e1y, e1z = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
    e2x, e2y, e2z = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
    nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    orientation = points[a, 0] * nx + points[a, 1] * ny + points[a, 2] * nz
    j0 = (e1x * r00, e1y * r00, e1z * r00)
    j1 = (e1x * r01 + e2x * r11, e1y * r01 + e2y * r11, e1z * r01 + e2z * r11)
    return (e1x, e1y, e1z), (e2x, e2y, e2z), j0, j1, (nx, ny, nz), orientation


@njit(cache=True)
def _face_energy(points, a, b, c, r00, r01, r11, area, weight, sign):
    """One triangle's term of the energy; infinite when its chord triangle is degenerate or
    flipped. ``r00, r01, r11`` are the entries of ``R^-1`` (see :class:`Dirichlet`)."""
    _, _, j0, j1, n, orientation = _face_parts(points, a, b, c, r00, r01, r11)
    orientation *= sign  # -1: a triangle left flipped, kept so (and its energy finite) until the end
    norm2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2]
    det = (r00 * r11) ** 2 * norm2
    if det <= 0.0 or orientation <= 0.0:
        return np.inf
    trace = j0[0] ** 2 + j0[1] ** 2 + j0[2] ** 2 + j1[0] ** 2 + j1[1] ** 2 + j1[2] ** 2
    # c = orientation / |n|: the chord plane's distance to the centre, 1 for a small triangle.
    return area * trace * (weight + 1.0 / det) * np.sqrt(norm2) / orientation


@njit(cache=True)
def _face_gradient(points, a, b, c, r00, r01, r11, area, weight, sign, out):
    """Gradient of :func:`_face_energy` with respect to its corners ``a, b, c``, into the rows
    of ``out`` (shape (3, 3))."""
    e1, e2, j0, j1, n, orientation = _face_parts(points, a, b, c, r00, r01, r11)
    orientation *= sign
    g00 = j0[0] * j0[0] + j0[1] * j0[1] + j0[2] * j0[2]
    g01 = j0[0] * j1[0] + j0[1] * j1[1] + j0[2] * j1[2]
    g11 = j1[0] * j1[0] + j1[1] * j1[1] + j1[2] * j1[2]
    norm = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    det = (r00 * r11 * norm) ** 2
    trace = g00 + g11
    barrier = norm / orientation  # 1 / c
    term = area * trace * (weight + 1.0 / det)
    # d(t w + t/d)/dJ = 2 J (w + 1/d) - 2 (t/d^2) J adj(G), adj(G) = [[g11, -g01], [-g01, g00]];
    # then back through J = E R^-1: dE = dJ R^-T; all times the barrier 1/c. Plus
    # term * d(|n| / o): d|n| = (de1 . (e2 x n) + de2 . (n x e1)) / |n|, and
    # do = dq0 . (q1 x q2) + dq1 . (q2 x q0) + dq2 . (q0 x q1).
    own = 2.0 * area * (weight + 1.0 / det) * barrier
    cross = 2.0 * area * trace / (det * det) * barrier
    s_norm = term / (orientation * norm)
    s_orient = -sign * term * norm / (orientation * orientation)
    for k in range(3):
        k1, k2 = (k + 1) % 3, (k + 2) % 3
        d0 = own * j0[k] - cross * (j0[k] * g11 - j1[k] * g01)
        d1 = own * j1[k] - cross * (j1[k] * g00 - j0[k] * g01)
        d_e1 = d0 * r00 + d1 * r01 + s_norm * (e2[k1] * n[k2] - e2[k2] * n[k1])
        d_e2 = d1 * r11 + s_norm * (n[k1] * e1[k2] - n[k2] * e1[k1])
        out[0, k] = -(d_e1 + d_e2) + s_orient * (
            points[b, k1] * points[c, k2] - points[b, k2] * points[c, k1]
        )
        out[1, k] = d_e1 + s_orient * (points[c, k1] * points[a, k2] - points[c, k2] * points[a, k1])
        out[2, k] = d_e2 + s_orient * (points[a, k1] * points[b, k2] - points[a, k2] * points[b, k1])


@njit(cache=True)
def _dirichlet_terms(faces, points, inverse, area, weight, sign):
    """Every triangle's :func:`_face_energy`, shape (F,)."""
    terms = np.empty(faces.shape[0])
    for f in range(faces.shape[0]):
        terms[f] = _face_energy(
            points, faces[f, 0], faces[f, 1], faces[f, 2], inverse[f, 0], inverse[f, 1], inverse[f, 2],
            area[f], weight, sign[f],
        )  # fmt: skip
    return terms


@njit(cache=True)
def _dirichlet_gradient(faces, points, inverse, area, weight, sign):
    """Gradient of :func:`_dirichlet_energy` with respect to ``points``, shape (V, 3)."""
    grad = np.zeros(points.shape)
    out = np.empty((3, 3))
    for f in range(faces.shape[0]):
        _face_gradient(
            points, faces[f, 0], faces[f, 1], faces[f, 2], inverse[f, 0], inverse[f, 1], inverse[f, 2],
            area[f], weight, sign[f], out,
        )  # fmt: skip
        for k in range(3):
            grad[faces[f, k]] += out[k]
    return grad


@njit(cache=True)
def _polish(faces, points, inverse, area, weight, sign, movers, vertex_faces, offsets, sweeps):
    """Lower the energy one vertex at a time (Gauss-Seidel over ``movers``), each along its own
    projected gradient under a backtracking line search on its triangles' terms alone, as
    Praun and Hoppe optimise a vertex in its 1-ring. Changes ``points`` in place."""
    out = np.empty((3, 3))
    for _ in range(sweeps):
        for v in movers:
            start, stop = offsets[v], offsets[v + 1]
            before = 0.0
            g = np.zeros(3)
            reach = np.inf
            for k in range(start, stop):
                f = vertex_faces[k]
                a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
                args = (inverse[f, 0], inverse[f, 1], inverse[f, 2], area[f], weight, sign[f])
                before += _face_energy(points, a, b, c, *args)
                _face_gradient(points, a, b, c, *args, out)
                for corner in range(3):
                    if faces[f, corner] == v:
                        g += out[corner]
                    else:
                        d = points[faces[f, corner]] - points[v]
                        reach = min(reach, np.sqrt(d @ d))
            p = points[v].copy()
            g -= (g @ p) * p
            size = np.sqrt(g @ g)
            if not (size > 0.0 and np.isfinite(before)):
                continue
            h = 0.5 * reach / size
            for _ in range(40):
                trial = p - h * g
                points[v] = trial / np.sqrt(trial @ trial)
                after = 0.0
                for k in range(start, stop):
                    f = vertex_faces[k]
                    after += _face_energy(
                        points, faces[f, 0], faces[f, 1], faces[f, 2], inverse[f, 0], inverse[f, 1],
                        inverse[f, 2], area[f], weight, sign[f],
                    )  # fmt: skip
                if after <= before - 1e-4 * h * size * size:
                    break
                h *= 0.5
            else:
                points[v] = p


class Dirichlet:
    """Symmetric Dirichlet energy of the map from the mesh triangles to the chord triangles.

    In the triangle's own plane its edges are the columns of ``R = [[l, a], [0, h]]``, and the
    Jacobian is ``J = [q1 - q0, q2 - q0] R^-1`` with ``R^-1 = [[1/l, -a/(l h)], [0, 1/h]]``;
    the energy is ``sum_f A_f (tr G + tr G / det G)``, ``G = J^T J``. Numba loops over the
    faces, since a step of the relaxation evaluates it several times.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, weight: float = 1.0, flipped=None):
        self.weight = float(weight)
        self.sign = np.ones(len(faces)) if flipped is None else np.where(flipped, -1.0, 1.0)
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

    def terms(self, points: np.ndarray) -> np.ndarray:
        """Each triangle's term, shape (F,); infinite where a triangle is flipped or degenerate."""
        return _dirichlet_terms(self.faces, points, self.inverse, self.area, self.weight, self.sign)

    def energy(self, points: np.ndarray) -> float:
        """The energy; infinite if a triangle is flipped or degenerate."""
        return float(self.terms(points).sum())

    def polish(self, points: np.ndarray, share: float = 0.02, sweeps: int = 20) -> np.ndarray:
        """``points`` after :func:`_polish` of the corners of the ``share`` of triangles with
        the highest energy per area (where a global step is held back)."""
        density = self.terms(points) / self.area
        worst = np.argsort(density)[-max(1, int(share * len(density))) :]
        movers = np.unique(self.faces[worst].ravel())
        order = np.argsort(self.faces.ravel(), kind="stable")
        offsets = np.searchsorted(self.faces.ravel()[order], np.arange(len(points) + 1))
        points = points.copy()
        _polish(
            self.faces,
            points,
            self.inverse,
            self.area,
            self.weight,
            self.sign,
            movers,
            order // 3,
            offsets,
            sweeps,
        )
        return points

    def gradient(self, points: np.ndarray) -> np.ndarray:
        return _dirichlet_gradient(self.faces, points, self.inverse, self.area, self.weight, self.sign)


def relax(vertices, faces, points, laplacian, masses, max_steps: int, tol: float, weight: float = 1.0):
    """Lower the symmetric Dirichlet energy on the sphere; returns (points, steps).

    Steps are preconditioned by the cotangent Laplacian (the Hessian of the Dirichlet part),
    projected to the tangent planes and renormalised to the sphere; a backtracking line search
    takes the longest that lowers the energy enough (the energy is infinite when a triangle
    flips); the triangles flipped at the start stay flipped.
    """
    from scipy.sparse import diags
    from scipy.sparse.linalg import splu

    # Triangles that the untangling left flipped stay so, with a finite energy, until the end.
    energy = Dirichlet(vertices, faces, weight, flipped(faces, points))
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
        # Scaled into single precision's range: crushed triangles give gradients past 1e38.
        scale = max(float(np.abs(grad).max()), 1e-300)
        direction = -scale * solve((grad / scale).astype(np.float32)).astype(np.float64)
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
            trial, value = points, current
        stalled = value == current
        points, current = trial, value
        history.append(current)
        # Over several steps, as single steps may gain little while a limb is still opening.
        if stalled or len(history) > _WINDOW and history[-1 - _WINDOW] - current < _WINDOW * tol * current:
            # A few triangles crushed or slivered (by an untangling) may hold back every global
            # step: move their corners one by one, and go on if that gained.
            polished = energy.polish(points)
            value = energy.energy(polished)
            if not current - value > max(_WINDOW * tol, 1e-12) * current:
                return points, iteration + 1
            points, current = polished, value
            history.append(current)
            # After a line search that failed (60 halvings), the step would only double back
            # from 2^-60: every later step would move nothing and the level stop unrelaxed.
            step = 1.0
    return points, max_steps


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
        ``stretch``: the L2 geometric stretch of Sander et al. (2001) of the map from the sphere
        to the surface scaled to the sphere's area (1 for an isometry, the least possible;
        Praun and Hoppe's stretch efficiency is ``1 / stretch^2``); ``mean_abs_log2``: mean of
        ``|log2 ratio|`` weighted by mesh area; ``p01``, ``p99``:
        1st and 99th percentiles of the ratio over the mesh area; ``min``, ``max``: its
        extremes; ``flips``: number of flipped triangles.
    """
    mesh_share = face_areas(vertices, faces)
    mesh_share /= mesh_share.sum()
    sphere_share = face_areas(points, faces)
    sphere_share /= sphere_share.sum()
    ratio = np.maximum(sphere_share, 1e-300) / np.maximum(mesh_share, 1e-300)
    order = np.argsort(ratio)
    cumulative = np.cumsum(mesh_share[order])
    p01, p99 = ratio[order][np.searchsorted(cumulative, [0.01, 0.99]).clip(0, ratio.size - 1)]
    # L2 geometric stretch (Sander et al. 2001) of the sphere -> surface map, the surface scaled
    # to the sphere's area: sqrt(mean over the surface of (1/s1^2 + 1/s2^2) / 2), 1 at best.
    scaled = vertices * np.sqrt(4 * np.pi / face_areas(vertices, faces).sum())
    inverse = Dirichlet(scaled, faces, 0.0)
    chord = np.cross(points[faces[:, 1]] - points[faces[:, 0]], points[faces[:, 2]] - points[faces[:, 0]])
    e1 = points[faces[:, 1]] - points[faces[:, 0]]
    e2 = points[faces[:, 2]] - points[faces[:, 0]]
    r00, r01, r11 = inverse.inverse.T
    trace = np.sum((e1 * r00[:, None]) ** 2 + (e1 * r01[:, None] + e2 * r11[:, None]) ** 2, axis=1)
    det = (r00 * r11) ** 2 * np.einsum("ij,ij->i", chord, chord)
    with np.errstate(divide="ignore"):
        stretch = np.sqrt(mesh_share @ (trace / det) / 2)
    return {
        "stretch": float(stretch),
        "mean_abs_log2": float(mesh_share @ np.abs(np.log2(ratio))),
        "p01": float(p01),
        "p99": float(p99),
        "min": float(ratio.min()),
        "max": float(ratio.max()),
        "flips": int(np.sum(flipped(faces, points))),
    }


def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    p = vertices[faces]
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
