"""Charts of a mesh of any topology, and their layout in one square image, from connectivity alone.

A mesh that is not a closed genus-0 surface (open, of any genus, of several parts) is cut into
charts, each a topological disk, and every chart is laid out in its own square of one image
(:mod:`.chartcodec` codes the vertex positions as that image). Everything here depends on the
faces only, never on the positions, so that the decoder, which receives the faces (a Draco
stream) but not the positions, redoes it exactly and no chart or coordinate is stored:

* :func:`region_charts`: compact regions grown from seeds spread by farthest-point sampling in
  hops across edges (about :data:`FACES_PER_CHART` faces each), then split until every one is a
  disk (:func:`disk_charts`: a region that closes round a handle or holds a hole is halved
  between the two ends of its longest path), and optionally merged again, neighbour with
  neighbour, into larger disks that stay round (:func:`merge_charts`);
* :func:`tutte_layout`: each chart's boundary loop on the perimeter of the unit square (its four
  corners on boundary vertices, the others evenly spaced by count), its interior vertices at the
  average of their neighbours (Tutte's embedding with uniform weights: no triangle folds, and
  the vertices spread evenly);
* :func:`pack`: the squares, of sides in proportion to the square root of their vertex counts,
  shelf-packed into the ``n x n`` image at the largest scale that fits (a treemap of
  rectangles filling the image, each chart's square stretched into its own, measured worse:
  cut sphere -7 dB, torus -1.5, fertility -1 at Draco's sizes: the stretch costs more than the
  unused pixels, which the smooth fit fills for almost nothing).

A vertex on a seam between charts is a vertex of each; its first chart (the lowest label) owns
it (:func:`owners`): only there does the image hold its position, the others leave the image
free to be smooth (measured on fertility.off at 8.9 bits per vertex: +1.5 dB Hausdorff PSNR
against averaging every copy).

Why not xatlas's charts: they must then be stored (their labels in Draco's face order cost 7.6
bits per vertex on rocker-arm.obj raw, LZMA-packed), and its flat, elongated charts mapped to
squares gave a lower ceiling (uncoded, 256 x 256: 63.1 dB against 71.6 for these regions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Layout",
    "boundary_loop",
    "disk_charts",
    "layout",
    "owners",
    "pack",
    "region_charts",
    "tutte_layout",
]

#: Free pixels between two charts' squares: the smooth fit (:func:`.atlas.fit`) makes a passage
#: across them, so the wavelets do not straddle two unrelated surfaces (1, 4 and 8 measured no
#: better on fertility.off).
PADDING = 2
#: Most squared boundary length over face count of a chart that :func:`merge_charts` makes: a
#: long or ragged chart crowds its vertices in Tutte's embedding.
MOST_ROUNDNESS = 20.0
#: Faces per chart that :func:`region_charts` aims at.
FACES_PER_CHART = 2000


def _dual_graph(faces: np.ndarray):
    """The faces' adjacency through shared edges, as a CSR matrix."""
    from scipy.sparse import coo_matrix

    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    n = int(faces.max()) + 1
    key = edges[:, 0] * n + edges[:, 1]
    order = np.argsort(key, kind="stable")
    same = key[order][1:] == key[order][:-1]
    a, b = order[:-1][same] // 3, order[1:][same] // 3
    return coo_matrix((np.ones(a.size), (a, b)), shape=(len(faces), len(faces))).tocsr()


def region_charts(
    faces: np.ndarray, faces_per_chart: int = FACES_PER_CHART, merge: bool = False
) -> np.ndarray:
    """Cut a mesh into compact regions from its connectivity alone (the decoder redoes it).

    Seeds by farthest-point sampling in hops across edges (every component has one, from its
    lowest face), about one per ``faces_per_chart`` faces; each face goes to its nearest seed
    (the lowest on ties). The regions are then split into disks by :func:`disk_charts`, and
    with ``merge`` merged again into larger disks by :func:`merge_charts`.

    Returns
    -------
    ndarray of int, shape (F,): labels, 0 to C - 1.
    """
    from scipy.sparse.csgraph import connected_components, shortest_path

    graph = _dual_graph(faces)
    n_components, component = connected_components(graph, directed=False)
    _, seeds = np.unique(component, return_index=True)
    seeds = list(seeds)
    target = max(n_components, int(round(len(faces) / faces_per_chart)))
    distance = shortest_path(graph, unweighted=True, indices=seeds, directed=False).min(axis=0)
    while len(seeds) < target:
        far = int(np.argmax(distance))
        if distance[far] < 2:
            break
        seeds.append(far)
        distance = np.minimum(distance, shortest_path(graph, unweighted=True, indices=far, directed=False))
    _, _, sources = _nearest_seed(graph, np.array(seeds))
    labels = disk_charts(faces, np.searchsorted(np.sort(seeds), sources))
    return merge_charts(faces, labels) if merge else labels


def _nearest_seed(graph, seeds: np.ndarray):
    from scipy.sparse.csgraph import dijkstra

    return dijkstra(
        graph, directed=False, indices=seeds, unweighted=True, min_only=True, return_predecessors=True
    )


def _face_components(faces: np.ndarray, members: np.ndarray) -> np.ndarray:
    """Label the faces ``members`` of ``faces`` by their connected components through shared
    edges (labels 0.., numbered in the order of their lowest face)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    sub = faces[members]
    edges = np.sort(sub[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    n = int(faces.max()) + 1
    key = edges[:, 0] * n + edges[:, 1]
    order = np.argsort(key, kind="stable")
    same = key[order][1:] == key[order][:-1]
    a, b = order[:-1][same] // 3, order[1:][same] // 3
    graph = coo_matrix((np.ones(a.size), (a, b)), shape=(len(sub), len(sub)))
    labels = connected_components(graph, directed=False)[1]
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(first.size, np.int64)
    rank[np.argsort(first)] = np.arange(first.size)
    return rank[labels]


def boundary_loop(faces: np.ndarray) -> np.ndarray | None:
    """The boundary loop of a set of faces if they form a topological disk, else ``None``.

    A disk: Euler characteristic 1 and one boundary loop, every boundary vertex on exactly two
    boundary edges. The loop starts at its lowest vertex and goes first to its lower neighbour,
    so that it depends on the connectivity only.
    """
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    if np.any(counts > 2):
        return None
    n_vertices = np.unique(faces).size
    if n_vertices - len(unique) + len(faces) != 1:
        return None
    border = unique[counts == 1]
    ends, valence = np.unique(border, return_counts=True)
    if np.any(valence != 2) or len(border) < 3:
        return None
    neighbours: dict[int, list[int]] = {int(v): [] for v in ends}
    for a, b in border.tolist():
        neighbours[a].append(b)
        neighbours[b].append(a)
    start = int(ends[0])
    loop = [start, min(neighbours[start])]
    while len(loop) < len(border):
        a, b = neighbours[loop[-1]]
        nxt = b if a == loop[-2] else a
        if nxt == start:
            return None  # a shorter loop: several boundary loops
        loop.append(nxt)
    return np.array(loop) if loop[-1] in neighbours[start] else None


def disk_charts(faces: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Split the charts until each is a topological disk connected through its edges.

    A chart that is not (:func:`boundary_loop`) is halved along a breadth-first order of its
    faces from its lowest one, and its halves split into their components, until every piece
    is a disk (a single triangle is one). Labels are renumbered in the order of each chart's
    lowest face.
    """
    from collections import deque

    out = np.full(len(faces), -1, np.int64)
    pending = deque()
    for chart in range(int(labels.max()) + 1):
        members = np.flatnonzero(labels == chart)
        for part in range(int(_face_components(faces, members).max()) + 1 if members.size else 0):
            pending.append(members[_face_components(faces, members) == part])
    count = 0
    while pending:
        members = np.sort(pending.popleft())
        if boundary_loop(faces[members]) is not None:
            out[members] = count
            count += 1
            continue
        nearer = _two_seeds(faces[members])
        for piece in (members[nearer], members[~nearer]):
            parts = _face_components(faces, piece)
            for part in range(int(parts.max()) + 1):
                pending.append(piece[parts == part])
    _, first = np.unique(out, return_index=True)
    rank = np.empty(first.size, np.int64)
    rank[np.argsort(first)] = np.arange(first.size)
    return rank[out]


def merge_charts(faces: np.ndarray, labels: np.ndarray, most_faces: int | None = None) -> np.ndarray:
    """Merge neighbouring disk charts while their union stays a disk (of at most ``most_faces``).

    In passes: the pairs of charts sharing the most edges first, each chart merged at most once
    a pass, until no pair merges. Fewer, larger charts mean fewer seams and chart borders in the
    image, where the positions jump from one chart to the next.
    """
    labels = labels.copy()
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    n = int(faces.max()) + 1
    key = edges[:, 0] * n + edges[:, 1]
    order = np.argsort(key, kind="stable")
    same = key[order][1:] == key[order][:-1]
    face_a, face_b = order[:-1][same] // 3, order[1:][same] // 3
    while True:
        a, b = labels[face_a], labels[face_b]
        across = a != b
        pairs = np.sort(np.column_stack([a[across], b[across]]), axis=1)
        if not len(pairs):
            break
        pairs, shared = np.unique(pairs, axis=0, return_counts=True)
        sizes = np.bincount(labels)
        touched: set[int] = set()
        merged = False
        for k in np.lexsort((pairs[:, 1], pairs[:, 0], -shared)):
            one, two = int(pairs[k, 0]), int(pairs[k, 1])
            if one in touched or two in touched:
                continue
            if most_faces is not None and sizes[one] + sizes[two] > most_faces:
                continue
            union = (labels == one) | (labels == two)
            loop = boundary_loop(faces[union])
            if loop is None or len(loop) ** 2 > MOST_ROUNDNESS * np.count_nonzero(union):
                continue
            labels[labels == two] = one
            touched.update((one, two))
            merged = True
        if not merged:
            break
    _, first = np.unique(labels, return_index=True)
    rank = np.full(labels.max() + 1, -1, np.int64)
    rank[labels[np.sort(first)]] = np.arange(first.size)
    return rank[labels]


def _two_seeds(faces: np.ndarray) -> np.ndarray:
    """Halve a connected set of faces: which are nearer (in hops) to one end of its longest
    path than to the other (found by two farthest-point steps from face 0)."""
    from scipy.sparse.csgraph import shortest_path

    graph = _dual_graph(faces)
    hops = shortest_path(graph, unweighted=True, indices=0, directed=False)
    one = int(np.argmax(np.where(np.isfinite(hops), hops, -1)))
    from_one = shortest_path(graph, unweighted=True, indices=one, directed=False)
    other = int(np.argmax(np.where(np.isfinite(from_one), from_one, -1)))
    from_other = shortest_path(graph, unweighted=True, indices=other, directed=False)
    nearer = from_one < from_other
    if nearer.all() or not nearer.any():  # two faces at most: split them apart
        nearer = np.arange(len(faces)) < (len(faces) + 1) // 2
    return nearer


def _perimeter(n: int) -> np.ndarray:
    """``n`` points round the unit square's perimeter, counter-clockwise from (0, 0), four of
    them on the corners when ``n >= 4``."""
    if n < 4:
        t = np.arange(n) / n * 4.0
    else:
        corners = np.round(np.arange(5) * n / 4.0).astype(np.int64)
        t = np.concatenate(
            [
                side + np.arange(corners[side + 1] - corners[side]) / (corners[side + 1] - corners[side])
                for side in range(4)
            ]
        )
    side = np.floor(t).astype(np.int64) % 4
    s = t - np.floor(t)
    x = np.choose(side, [s, np.ones_like(s), 1 - s, np.zeros_like(s)])
    y = np.choose(side, [np.zeros_like(s), s, np.ones_like(s), 1 - s])
    return np.column_stack([x, y])


@dataclass(frozen=True)
class Layout:
    """Where every chart vertex lies in the image.

    Attributes
    ----------
    corner_vertex : ndarray of int, shape (K,)
        The mesh vertex of each chart vertex (a vertex on a seam is one chart vertex per chart).
    corner_chart : ndarray of int, shape (K,)
    uv : ndarray of float, shape (K, 2)
        Its place in its chart's unit square.
    face_corners : ndarray of int, shape (F, 3)
        The chart vertices of every face.
    pixels : ndarray of float, shape (K, 2)
        Its (row, column) in the image, pixel centres at integers.
    """

    corner_vertex: np.ndarray
    corner_chart: np.ndarray
    uv: np.ndarray
    face_corners: np.ndarray
    pixels: np.ndarray


def tutte_layout(
    faces: np.ndarray, labels: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each chart's Tutte embedding in the unit square (uniform weights; one sparse solve).

    Returns
    -------
    corner_vertex, corner_chart, uv, face_corners
        See :class:`Layout`.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    n_vertices = int(faces.max()) + 1
    key = labels[:, None] * n_vertices + faces  # one chart vertex per (chart, vertex)
    unique, face_corners = np.unique(key.ravel(), return_inverse=True)
    face_corners = face_corners.reshape(faces.shape)
    corner_chart, corner_vertex = unique // n_vertices, unique % n_vertices
    uv = np.zeros((len(unique), 2))
    fixed = np.zeros(len(unique), bool)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(int(labels.max()) + 2))
    for chart in range(int(labels.max()) + 1):
        members = order[bounds[chart] : bounds[chart + 1]]
        loop = boundary_loop(face_corners[members])
        if loop is None:
            raise ValueError(f"chart {chart} is not a topological disk")
        uv[loop] = _perimeter(len(loop))
        fixed[loop] = True
    edges = np.unique(np.sort(face_corners[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    a = np.concatenate([edges[:, 0], edges[:, 1]])
    b = np.concatenate([edges[:, 1], edges[:, 0]])
    free = np.flatnonzero(~fixed)
    if free.size:
        index = np.full(len(unique), -1)
        index[free] = np.arange(free.size)
        degree = np.bincount(a, minlength=len(unique)).astype(np.float64)
        inner = (index[a] >= 0) & (index[b] >= 0)
        matrix = coo_matrix(
            (
                np.concatenate([degree[free], -np.ones(int(inner.sum()))]),
                (
                    np.concatenate([np.arange(free.size), index[a[inner]]]),
                    np.concatenate([np.arange(free.size), index[b[inner]]]),
                ),
            ),
            shape=(free.size, free.size),
        ).tocsc()
        toward = (index[a] >= 0) & fixed[b]
        rhs = np.zeros((free.size, 2))
        np.add.at(rhs, index[a[toward]], uv[b[toward]])
        uv[free] = spsolve(matrix, rhs).reshape(-1, 2)
    return corner_vertex, corner_chart, uv, face_corners


def pack(counts: np.ndarray, side: int, padding: int = PADDING) -> tuple[np.ndarray, np.ndarray]:
    """Shelf-pack squares of sides in proportion to ``sqrt(counts)`` into a ``side``-pixel square.

    Parameters
    ----------
    counts : ndarray of int, shape (C,)
        Vertices of every chart.
    side : int
        Side of the image.

    Returns
    -------
    origin : ndarray of int, shape (C, 2)
        (row, column) of each square's first pixel.
    sizes : ndarray of int, shape (C,)
        Side of each square in pixels (at least 2).

    Raises
    ------
    ValueError
        If the charts do not fit even at the smallest size.
    """
    counts = np.asarray(counts, np.float64)
    order = np.argsort(-counts, kind="stable")

    def attempt(scale: float) -> tuple[np.ndarray, np.ndarray] | None:
        sizes = np.maximum(2, np.floor(scale * np.sqrt(counts)).astype(np.int64))
        origin = np.zeros((len(counts), 2), np.int64)
        row = column = shelf = 0
        for chart in order:
            size = int(sizes[chart])
            if column + size > side:
                row, column, shelf = row + shelf + padding, 0, 0
            if column + size > side or row + size > side:
                return None
            origin[chart] = row, column
            column += size + padding
            shelf = max(shelf, size)
        return origin, sizes

    low, high = 0.0, float(side) / np.sqrt(counts.max())
    best = attempt(low)
    if best is None:
        raise ValueError(f"{len(counts)} charts do not fit in a {side} x {side} image; use a larger one")
    for _ in range(40):  # bisect on the scale: the same steps at the encoder and the decoder
        middle = 0.5 * (low + high)
        found = attempt(middle)
        if found is None:
            high = middle
        else:
            low, best = middle, found
    return best


def owners(layout_: Layout) -> np.ndarray:
    """Which chart vertices own their mesh vertex (the copy in the lowest chart), shape (K,)."""
    # Chart vertices are numbered by (chart, vertex): the first of each vertex is its lowest chart.
    _, first = np.unique(layout_.corner_vertex, return_index=True)
    owned = np.zeros(len(layout_.corner_vertex), bool)
    owned[first] = True
    return owned


def layout(faces: np.ndarray, labels: np.ndarray, side: int) -> Layout:
    """The chart vertices of a mesh cut into disk charts, placed in a ``side x side`` image."""
    corner_vertex, corner_chart, uv, face_corners = tutte_layout(faces, labels)
    counts = np.bincount(corner_chart)
    origin, sizes = pack(counts, side)
    pixels = origin[corner_chart] + uv[:, ::-1] * (sizes[corner_chart, None] - 1)
    return Layout(corner_vertex, corner_chart, uv, face_corners, pixels)
