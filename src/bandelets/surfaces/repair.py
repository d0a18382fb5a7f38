"""Non-manifold meshes split into manifold pieces, as mesh repair tools do.

An edge on more than two faces, or a vertex whose faces form several fans (a pinched vertex:
two cones touching at their tips), has no disk around it, and neither Edgebreaker (Draco) nor a
chart's embedding takes it. :func:`manifold_pieces` cuts the surface along every such edge and
gives each fan of faces round a vertex its own copy of the vertex (MeshLab's "split non-manifold
vertices" does the same for vertices): the faces are kept, each one once, and the pieces meet
where they met, at copies of the same position; the decoded mesh has them apart (welded by
position it is the input again, up to the coding error).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Split", "manifold_pieces"]


@dataclass(frozen=True)
class Split:
    """What :func:`manifold_pieces` did.

    Attributes
    ----------
    edges : int
        Edges that were on more than two faces.
    vertices : int
        Vertices given more than one copy (on those edges, or pinched).
    copies : int
        Vertices added.
    first_edge : tuple of int or None
        The first (lowest) non-manifold edge's vertices, if any.
    """

    edges: int
    vertices: int
    copies: int
    first_edge: tuple[int, int] | None

    def __bool__(self) -> bool:
        return self.copies > 0

    def summary(self) -> str:
        """One line: ``"split into manifold pieces: 1 non-manifold edge (first: vertices 0-1),
        2 vertices copied (+4)"``; ``""`` if nothing was split."""
        if not self:
            return ""
        edges = ""
        if self.edges:
            a, b = self.first_edge
            edges = f"{self.edges} non-manifold edge{'s' * (self.edges != 1)} (first: vertices {a}-{b}), "
        return (
            f"split into manifold pieces: {edges}{self.vertices} "
            f"vert{'ices' if self.vertices != 1 else 'ex'} copied (+{self.copies})"
        )


def manifold_pieces(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, Split]:
    """Cut a mesh along its non-manifold edges and at its pinched vertices.

    Two faces stay joined through an edge only where the edge is on exactly two faces; every
    fan of faces joined round a vertex gets its own vertex (the fan of the vertex's first face
    corner keeps the vertex's index, the others are appended after the input's vertices).

    Parameters
    ----------
    vertices : ndarray of float, shape (V, 3)
    faces : ndarray of int, shape (F, 3)
        Triangles with three distinct vertices each.

    Returns
    -------
    vertices : ndarray of float, shape (V + copies, 3)
    faces : ndarray of int, shape (F, 3)
        The same faces, in the same order, on the split vertices.
    split : Split
    """
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces, np.int64)
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_faces = len(faces)
    start, end = faces.ravel(), np.roll(faces, -1, axis=1).ravel()  # the edge after each corner
    corner = np.arange(3 * n_faces).reshape(n_faces, 3)
    start_corner, end_corner = corner.ravel(), np.roll(corner, -1, axis=1).ravel()
    low, high = np.minimum(start, end), np.maximum(start, end)
    n = int(faces.max()) + 1
    key = low * n + high
    order = np.argsort(key, kind="stable")
    keys, first, counts = np.unique(key[order], return_index=True, return_counts=True)
    bad = counts > 2
    # The corners at an edge's lower and higher vertex, for every face on it.
    at_low = np.where(start == low, start_corner, end_corner)[order]
    at_high = np.where(start == low, end_corner, start_corner)[order]
    pair = first[counts == 2]  # manifold edges: their two faces' corners meet at both ends
    a = np.concatenate([at_low[pair], at_high[pair]])
    b = np.concatenate([at_low[pair + 1], at_high[pair + 1]])
    _, fan = connected_components(
        coo_matrix((np.ones(a.size), (a, b)), shape=(3 * n_faces, 3 * n_faces)), directed=False
    )
    vertex_of_fan = np.zeros(fan.max() + 1, np.int64)
    vertex_of_fan[fan] = faces.ravel()
    fans_per_vertex = np.bincount(vertex_of_fan, minlength=len(vertices))
    if not np.any(fans_per_vertex > 1):
        return vertices, faces, Split(0, 0, 0, None)
    # Each vertex's fan of lowest corner keeps the vertex; the others are new vertices.
    lowest_corner = np.full(fan.max() + 1, 3 * n_faces, np.int64)
    np.minimum.at(lowest_corner, fan, np.arange(3 * n_faces))
    by_vertex = np.lexsort((lowest_corner, vertex_of_fan))
    is_first = np.ones(by_vertex.size, bool)
    is_first[1:] = vertex_of_fan[by_vertex][1:] != vertex_of_fan[by_vertex][:-1]
    new_index = np.empty(fan.max() + 1, np.int64)
    new_index[by_vertex[is_first]] = vertex_of_fan[by_vertex[is_first]]
    extra = by_vertex[~is_first]
    new_index[extra] = len(vertices) + np.arange(extra.size)
    split_vertices = np.concatenate([vertices, vertices[vertex_of_fan[extra]]])
    first_edge = None
    if bad.any():
        k = int(keys[bad][0])
        first_edge = (k // n, k % n)
    split = Split(int(bad.sum()), int(np.sum(fans_per_vertex > 1)), int(extra.size), first_edge)
    return split_vertices, new_index[fan].reshape(n_faces, 3), split
