"""Checks that a triangle mesh can be mapped to the sphere.

A spherical parameterization needs a closed, edge- and vertex-manifold, connected surface of
genus 0, without zero-area triangles (the parameterization divides by every triangle's area).
:func:`check_genus0` names the first thing that is wrong.
"""

from __future__ import annotations

import numpy as np

__all__ = ["check_genus0", "check_memory", "edge_face_counts", "flat_triangles"]

#: Peak bytes per face of the checks and the spherical parameterization (peak resident memory above
#: the loaded mesh, encoding a 64 x 64 geometry image; coarse-to-fine map, benchmarks/mesh_memory.py:
#: 1,400 B/face for 445,824 faces, 1,676 for 111,456, 1,948 for 66,472; 4,575 for 27,864, where
#: fixed costs of about 100 MiB, the imports of pymeshlab and scipy's solvers among them, dominate),
#: rounded up.
MEMORY_PER_FACE = 2560
#: A triangle whose height is below this fraction of its longest edge counts as flat (zero area).
FLAT = 1e-12


def edge_face_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The undirected edges of a triangle mesh and how many faces hold each.

    Parameters
    ----------
    faces : ndarray of int, shape (F, 3)

    Returns
    -------
    edges : ndarray of int, shape (E, 2)
        Sorted vertex pairs, each once.
    counts : ndarray of int, shape (E,)
        Number of faces on each edge: 1 on an open boundary, 2 on a manifold edge.
    """
    pairs = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1).astype(np.int64)
    n = int(pairs.max()) + 1
    # One integer per pair: np.unique on integers is much faster than on rows.
    keys, counts = np.unique(pairs[:, 0] * n + pairs[:, 1], return_counts=True)
    return np.column_stack([keys // n, keys % n]), counts


def flat_triangles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Which triangles have (numerically) zero area: collinear or coincident vertices.

    Parameters
    ----------
    vertices : ndarray of float, shape (V, 3)
    faces : ndarray of int, shape (F, 3)

    Returns
    -------
    ndarray of bool, shape (F,): twice the area at most :data:`FLAT` times the squared longest edge.
    """
    corners = np.asarray(vertices, np.float64)[faces]
    edges = corners[:, [1, 2, 0]] - corners
    twice_area = np.linalg.norm(np.cross(edges[:, 0], edges[:, 1]), axis=1)
    longest = np.max(np.einsum("fkc,fkc->fk", edges, edges), axis=1)
    return twice_area <= FLAT * longest


def check_memory(n_faces: int, max_memory: int) -> None:
    """Raise ``ValueError`` if parameterizing a mesh of ``n_faces`` triangles needs more than
    ``max_memory`` bytes (:data:`MEMORY_PER_FACE`)."""
    need = MEMORY_PER_FACE * n_faces
    if need > max_memory:
        raise ValueError(
            f"parameterizing a mesh of {n_faces} faces needs about {need / 2**20:.0f} MiB, above the limit "
            f"of {max_memory / 2**20:.0f} MiB (max_memory)"
        )


def _components(n_nodes: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(a.size), (a, b)), shape=(n_nodes, n_nodes))
    return connected_components(graph, directed=False)


def _vertex_fans(faces: np.ndarray) -> int:
    """Number of fans of faces around the vertices (one per vertex on a manifold mesh).

    The nodes are the face corners; two corners at the same vertex are joined when their
    faces share an edge at that vertex.
    """
    n_faces = faces.shape[0]
    corner = np.arange(3 * n_faces).reshape(n_faces, 3)
    # Directed edge (faces[f, k], faces[f, k+1]) starts at corner k and ends at corner k+1.
    start = faces.ravel()
    end = np.roll(faces, -1, axis=1).ravel()
    start_corner = corner.ravel()
    end_corner = np.roll(corner, -1, axis=1).ravel()
    # Match each directed edge (a, b) with its opposite (b, a) in the neighbouring face.
    n = int(faces.max()) + 1
    key = start.astype(np.int64) * n + end
    order = np.argsort(key)
    opposite = end.astype(np.int64) * n + start
    where = np.searchsorted(key[order], opposite)
    where = np.minimum(where, key.size - 1)
    found = key[order][where] == opposite
    mate = order[where][found]
    # The corner at a of this edge meets the corner at a of the mate (its end corner), and so on.
    a = np.concatenate([start_corner[found], end_corner[found]])
    b = np.concatenate([end_corner[mate], start_corner[mate]])
    return _components(3 * n_faces, a, b)[0]


def _count(n: int, noun: str, plural: str = "") -> str:
    """``"1 edge"``, ``"2 edges"``."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


def check_genus0(vertices: np.ndarray, faces: np.ndarray) -> None:
    """Raise ``ValueError`` unless the mesh is a closed, manifold, connected genus-0 surface.

    Parameters
    ----------
    vertices : ndarray of float, shape (V, 3)
        Positions (any unit); every vertex must be used by a face.
    faces : ndarray of int, shape (F, 3)
        Triangles, consistently oriented.

    Raises
    ------
    ValueError
        Naming what is wrong: no faces, coordinates that are not finite (NaN, inf), unused
        vertices, zero-area triangles, several components, an open boundary, non-manifold edges
        or vertices, inconsistent orientation, or genus g > 0.
    """
    faces = np.asarray(faces, dtype=np.int64)
    n_vertices = len(vertices)
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.shape[0] < 4:
        raise ValueError(f"expected a closed triangle mesh, got faces of shape {faces.shape}")
    if not np.all(np.isfinite(vertices)):  # NaN or inf: the relaxation's solver would fail on them
        raise ValueError("some vertex coordinates are not finite numbers (NaN or infinite)")
    if faces.min() < 0 or faces.max() >= n_vertices:
        raise ValueError("faces refer to vertices that do not exist")
    if np.any((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])):
        raise ValueError("some faces repeat a vertex (degenerate triangles)")
    unused = n_vertices - np.unique(faces).size
    if unused:
        raise ValueError(f"{_count(unused, 'vertex', 'vertices')} used by no face")
    flat = int(np.sum(flat_triangles(vertices, faces)))
    if flat:
        raise ValueError(
            f"{_count(flat, 'triangle')} of zero area (collinear or coincident vertices); "
            "remove or repair them"
        )
    edges, counts = edge_face_counts(faces)
    n_components = _components(n_vertices, edges[:, 0], edges[:, 1])[0]
    if n_components > 1:
        raise ValueError(f"the mesh has several components ({n_components}); expected one")
    if np.any(counts == 1):
        raise ValueError(
            f"the mesh is not closed: open boundary of {_count(int(np.sum(counts == 1)), 'edge')} "
            "(holes must be filled)"
        )
    if np.any(counts > 2):
        raise ValueError(
            f"the mesh has {_count(int(np.sum(counts > 2)), 'non-manifold edge')} (on more than two faces)"
        )
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    if np.unique(directed[:, 0] * n_vertices + directed[:, 1]).size != 2 * edges.shape[0]:
        raise ValueError("the faces are not consistently oriented (or the surface is not orientable)")
    fans = _vertex_fans(faces)
    if fans != n_vertices:
        raise ValueError(
            f"the mesh has {_count(fans - n_vertices, 'non-manifold vertex', 'non-manifold vertices')} "
            "(pinched fans)"
        )
    euler = n_vertices - edges.shape[0] + faces.shape[0]
    if euler != 2:
        raise ValueError(f"the surface has genus {(2 - euler) // 2}; spherical geometry images need genus 0")
