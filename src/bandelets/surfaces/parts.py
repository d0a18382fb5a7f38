"""Meshes of several parts, some of them closed genus-0 surfaces: each such part on the spherical
path, the rest together on the multi-chart route, in one file.

A mesh of several components is refused by the spherical path (:mod:`.codec`) as a whole, but
each of its closed genus-0 components is a mesh that path codes far better than the multi-chart
route (:mod:`.chartcodec`): the bunny and the fandisk in one file at Draco's quantization-7
size, 7,859 bytes, measured 71.7 dB Hausdorff PSNR as two spherical files against 58.9 dB as
one multi-chart image. The encoder (:func:`encode_parts`) codes each such part as a file of its
own (at most :data:`MOST_SPHERES` of them, the largest), and every other component together as
one more file (the chart route), the bits shared in proportion to the vertex counts. The caller
(:func:`.codec.encode_mesh`) keeps this record alone when there is no such rest and the rate is
low (:data:`.codec.RECORD_ALONE_BELOW`), else this record or the chart route's file of the whole
mesh, whichever measures better (:func:`better`).

The decoded mesh is the parts' decoded meshes one after the other: each part keeps its identity
(a component of its own), a spherical part comes back with its own vertex count (simplified from
its geometry image as :func:`.codec.decode_mesh` does) and the rest with its faces.

Record layout (little endian)::

    offset  size  field
    0       4     magic b"BDLP"
    4       1     record version (RECORD_VERSION, 1)
    5       ...   count of parts (unsigned LEB128)
    ...     ...   per part: byte length (unsigned LEB128), then a whole mesh file (a spherical
                  geometry image .bdl or a chart mesh record, each with its own CRC)
    end-4   4     CRC32 of everything before it
"""

from __future__ import annotations

import zlib
from collections.abc import Callable

import numpy as np

from ..format.varint import read_varint, varint
from . import checks

__all__ = [
    "FEWEST_VERTICES",
    "MAGIC",
    "MOST_SPHERES",
    "RECORD_VERSION",
    "better",
    "encode_parts",
    "files",
    "is_parts_file",
    "join",
    "split",
]

MAGIC = b"BDLP"
RECORD_VERSION = 1
#: Most parts coded on the spherical path (each file has a header of its own, each part a
#: parameterization): the largest closed genus-0 components, the others join the rest.
MOST_SPHERES = 8
#: Fewest vertices of a part coded on the spherical path: smaller ones join the rest.
FEWEST_VERTICES = 64


def is_parts_file(data: bytes) -> bool:
    """Whether ``data`` starts as a record of parts."""
    return bytes(data[:4]) == MAGIC


def _is_genus0(vertices: np.ndarray, faces: np.ndarray) -> bool:
    try:
        checks.check_genus0(vertices, faces)
    except ValueError:
        return False
    return True


def split(vertices: np.ndarray, faces: np.ndarray) -> list | None:
    """The parts of a manifold mesh: its largest closed genus-0 components (up to
    :data:`MOST_SPHERES`, of :data:`FEWEST_VERTICES` or more) each alone, then every other
    component together (if any), as ``trimesh.Trimesh`` objects; ``None`` if no component is
    such a part.
    """
    import trimesh
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    vertices, faces = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    n = len(vertices)
    rows, columns = faces[:, [0, 1]].ravel(), faces[:, [1, 2]].ravel()
    graph = coo_matrix((np.ones(rows.size), (rows, columns)), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    face_label = labels[faces[:, 0]]
    pieces = []
    for label in range(count):
        own = faces[face_label == label]
        if own.size == 0:
            continue
        used, compact = np.unique(own, return_inverse=True)
        pieces.append((vertices[used], compact.reshape(-1, 3)))
    closed = [k for k, (v, f) in enumerate(pieces) if len(v) >= FEWEST_VERTICES and _is_genus0(v, f)]
    spheres = sorted(sorted(closed, key=lambda k: -len(pieces[k][0]))[:MOST_SPHERES])
    if not spheres:
        return None
    parts = [trimesh.Trimesh(*pieces[k], process=False) for k in spheres]
    rest = [pieces[k] for k in range(len(pieces)) if k not in set(spheres)]
    if rest:
        offsets = np.cumsum([0] + [len(v) for v, _ in rest])
        parts.append(
            trimesh.Trimesh(
                np.concatenate([v for v, _ in rest]),
                np.concatenate([f + o for (_, f), o in zip(rest, offsets[:-1], strict=True)]),
                process=False,
            )
        )
    return parts


def encode_parts(
    parts: list, bits: float, encode: Callable[[object, int], bytes], fixed: list[int] | None = None
) -> bytes:
    """A record of ``parts`` (:func:`split`) in at most ``bits`` bits.

    Parameters
    ----------
    parts : list of trimesh.Trimesh
    bits : float
        Most bits of the record.
    encode : callable
        ``encode(part, n_bytes)``: the mesh file of one part in at most ``n_bytes`` bytes
        (:func:`.codec.encode_mesh`).
    fixed : list of int, optional
        Bytes of each part's file that are not its positions (the faces of the rest, on the chart
        route; none on the spherical path): each part gets them, and a share of the remaining
        bytes in proportion to its vertex count.

    Raises
    ------
    ValueError
        A part's file does not fit its share of the bits.
    """
    counts = np.array([len(part.vertices) for part in parts], dtype=np.float64)
    overhead = len(MAGIC) + 1 + len(varint(len(parts))) + 3 * len(parts) + 4
    fixed = [0] * len(parts) if fixed is None else fixed
    budget = bits / 8.0 - overhead - sum(fixed)
    body = MAGIC + bytes([RECORD_VERSION]) + varint(len(parts))
    for part, count, own in zip(parts, counts, fixed, strict=True):
        data = encode(part, int(own + budget * count / counts.sum()))
        body += varint(len(data)) + data
    return body + zlib.crc32(body).to_bytes(4, "little")


def files(data: bytes) -> list[bytes]:
    """The parts' mesh files in a record of parts.

    Raises
    ------
    ValueError
        A record that is corrupt, truncated or of an unknown version.
    """
    data = bytes(data)
    if len(data) < 10 or not is_parts_file(data):
        raise ValueError("not a parts mesh file")
    if zlib.crc32(data[:-4]) != int.from_bytes(data[-4:], "little"):
        raise ValueError("corrupt parts mesh file (CRC mismatch)")
    if data[4] != RECORD_VERSION:
        raise ValueError(f"parts mesh record version {data[4]}; this build reads version {RECORD_VERSION}")
    count, offset = read_varint(data, 5, len(data) - 4, "corrupt parts mesh file")
    out = []
    for _ in range(count):
        length, offset = read_varint(data, offset, len(data) - 4, "corrupt parts mesh file")
        if offset + length > len(data) - 4:
            raise ValueError("truncated parts mesh file")
        out.append(data[offset : offset + length])
        offset += length
    if not out or offset != len(data) - 4:
        raise ValueError("corrupt parts mesh file (part lengths)")
    return out


def join(meshes: list):
    """One mesh of ``meshes``, one after the other (nothing merged)."""
    import trimesh

    offsets = np.cumsum([0] + [len(mesh.vertices) for mesh in meshes])
    return trimesh.Trimesh(
        np.concatenate([np.asarray(mesh.vertices, np.float64) for mesh in meshes]),
        np.concatenate(
            [np.asarray(mesh.faces, np.int64) + o for mesh, o in zip(meshes, offsets[:-1], strict=True)]
        ),
        process=False,
    )


def better(mesh, candidates: list[bytes], decode: Callable[[bytes], object], samples: int) -> bytes:
    """The candidate file whose decoded mesh (``decode``) measures the best Hausdorff PSNR against
    ``mesh`` (``samples`` samples a side)."""
    from .metrics import hausdorff_psnr

    def score(data: bytes) -> float:
        try:
            return hausdorff_psnr(mesh, decode(data), samples)
        except ValueError:  # a decoded mesh of no area
            return -np.inf

    return max(candidates, key=score)
