"""Meshes of any topology (open, any genus, several parts) as multi-chart geometry images.

The route for every mesh that the spherical path (:mod:`.codec`) refuses. The decoded mesh has
the input's faces and vertex count: its components, boundary loops and genus are the input's,
and it has no crack anywhere (a vertex on a seam between charts is one vertex). Only the
positions are lossy:

1. the faces go into a Draco stream (Edgebreaker, 0.5 to 2.5 bits per vertex) with dummy
   positions that cost almost nothing (the decoder drops them);
2. both sides cut the decoded faces into disk charts and lay them out in one square image from
   the faces alone (:mod:`.charts`), so no chart, seam or coordinate is stored;
3. the positions become the smoothest image whose bilinear reads at the vertices are the
   positions (:func:`.atlas.fit`), coded by the image codec (kind ``geometry-image``, local
   frames, symmetric extension);
4. the decoder reads every vertex at its place in its first chart.

The best cut into charts depends on the mesh: small regions merged into a few large disks
lead on a torus (+9 dB at 3.9 bits per vertex) and a cut sphere (+12 dB), and trail on
rocker-arm.obj (-9 dB), whose merged charts are long and thin. The encoder codes the mesh with
each of :data:`CHART_VARIANTS` (up to :data:`TRIED_UP_TO` vertices; above, the first only) and
keeps the file of the best Hausdorff PSNR (:data:`TRIAL_SAMPLES` samples a side); one byte says
which. It then tries the sides :data:`SIDE_FACTORS` times the default in the same way (the
image's header holds its side), and last a normal layer (:mod:`.normallayer`) beside the image at
part of the bits, at the best side and at the smaller one that suits the image's fewer bits, the
best of those once more with the image restored by the decoder (the torus at Draco's
quantization-7 size: +2.56 -> +3.39 dB over Draco).

File layout (a mesh record of its own, not a plain .bdl image; little endian)::

    offset  size  field
    0       4     magic b"BDLC"
    4       1     record version (RECORD_VERSION, 2; version 1 is read too: no LAYER flag)
    5       1     the charts: an index into CHART_VARIANTS (faces per seed, merged or not),
                  plus LAYER (0x40) if a normal layer follows the image; or DRACO_ONLY (255):
                  the Draco stream is then Draco's own file of the mesh, its positions the
                  decoded ones, and no geometry image follows
    6       ...   byte length of the Draco stream (unsigned LEB128)
    ...     ...   the Draco stream: the faces, in the order the decoder numbers the vertices
    with LAYER:   byte length of the image (unsigned LEB128), the image, the layer's step
                  and gain (two float32), the layer (:mod:`.normallayer`: one offset along the normal a
                  vertex, range coded) up to the CRC
    without:      the geometry image: a whole .bdl file (its own header and CRC32) of kind
                  geometry-image, 3 channels, square of even side, symmetric extension
    end-4   4     CRC32 of everything before it

Versions 1 and 2's charts and layout are those of :func:`.charts.region_charts` and
:func:`.charts.layout` with their constants of this version (:data:`.charts.FACES_PER_CHART`,
:data:`.charts.PADDING`); changing them needs a new record version.
"""

from __future__ import annotations

import dataclasses
import struct
import zlib

import numpy as np

from ..codec.decoder import decode_parsed
from ..codec.encoder import encode_with_stats
from ..codec.options import EncodeOptions
from ..format.fields import DEFAULT_NORMAL_WEIGHT, MAX_MEMORY
from ..format.header import unpack

# The codec's names through the spherical path's module, whose imports follow the package's layout.
from ..format.varint import read_varint, varint
from . import atlas, charts, checks, draco, normallayer, repair

__all__ = [
    "DRACO_ONLY",
    "MAGIC",
    "CHART_VARIANTS",
    "RECORD_VERSION",
    "chart_side",
    "check_surface",
    "decode_charts",
    "describe",
    "encode_charts",
    "faces_bytes",
    "fitting_side",
    "is_chart_file",
]

MAGIC = b"BDLC"
RECORD_VERSION = 2
#: Image side over the square root of the vertex count: fertility.off (4,494 vertices) measured
#: best at 72 to 80 pixels, rocker-arm.obj (10,044) at 128 to 160 (at Draco's sizes).
SIDE_PER_ROOT_VERTEX = 1.25
#: The cuts into charts a file may use: faces per seed of :func:`.charts.region_charts`, and
#: whether the regions are merged into larger disks.
CHART_VARIANTS = ((2000, False), (500, True), (250, True), (125, True))
#: The record's variant byte when it holds Draco's own file of the mesh, positions and all (where
#: no geometry image pays: the encoder measures both at the asked size and keeps the better).
DRACO_ONLY = 255
#: Flag of the variant byte (record version 2): a normal layer follows the image (:mod:`.normallayer`).
LAYER = 0x40
#: Most vertices of a mesh for which the encoder tries every variant.
TRIED_UP_TO = 30_000
TRIAL_SAMPLES = 20_000
#: Sides the encoder also tries, over :func:`chart_side`'s, with the best cut into charts.
SIDE_FACTORS = (0.8, 1.25)
#: Draco's bits for the positions that carry the faces (the fewest it takes).
CARRIER_BITS = 1
#: Bits of the positions through which the encoder learns Draco's vertex order.
ORDER_BITS = 20


def is_chart_file(data: bytes) -> bool:
    """Whether ``data`` starts as a chart mesh record."""
    return bytes(data[:4]) == MAGIC


def chart_side(n_vertices: int) -> int:
    """Side of the geometry image of a mesh of ``n_vertices`` vertices (even, 8 to 4096)."""
    side = int(round(SIDE_PER_ROOT_VERTEX * np.sqrt(n_vertices) / 2.0)) * 2
    return int(np.clip(side, 8, 4096))


def check_surface(vertices, faces) -> tuple[np.ndarray, np.ndarray, repair.Split]:
    """The vertices and faces of a mesh the chart route can code, unused vertices dropped and
    non-manifold edges and pinched vertices split into manifold pieces (:mod:`.repair`).

    Returns
    -------
    vertices, faces : ndarray
    split : repair.Split
        What was split (nothing on a manifold mesh).

    Raises
    ------
    ValueError
        One line naming what is wrong: no faces, non-finite coordinates, a single triangle,
        faces repeating a vertex, triangles of zero area, an edge that no split makes manifold.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.shape[0] == 0:
        raise ValueError("the mesh has no triangles")
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"expected vertices of shape (V, 3), got {vertices.shape}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ValueError("faces refer to vertices that do not exist")
    bad = np.flatnonzero(~np.all(np.isfinite(vertices[np.unique(faces)]), axis=1))
    if bad.size:
        raise ValueError(f"vertex {np.unique(faces)[bad[0]]} has a non-finite coordinate (NaN or infinity)")
    if faces.shape[0] == 1:
        raise ValueError("the mesh is a single triangle: nothing to code as a surface")
    repeated = np.flatnonzero(
        (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    )
    if repeated.size:
        verb = "repeats" if repeated.size == 1 else "repeat"
        raise ValueError(f"{_faces(repeated.size)} {verb} a vertex (degenerate; first: face {repeated[0]})")
    flat = np.flatnonzero(checks.flat_triangles(vertices, faces))
    if flat.size:
        raise ValueError(
            f"{_faces(flat.size)} of zero area (degenerate; first: face {flat[0]}); remove or repair them"
        )
    used, compact = np.unique(faces, return_inverse=True)
    vertices, split_faces, split = repair.manifold_pieces(vertices[used], compact.reshape(-1, 3))
    edges, counts = checks.edge_face_counts(split_faces)
    if np.any(counts > 2):  # faces joined round both ends of the edge: no split frees them
        origin = np.empty(len(vertices), np.int64)
        origin[split_faces.ravel()] = faces.ravel()
        a, b = origin[edges[np.argmax(counts > 2)]]
        raise ValueError(
            f"non-manifold edge between vertices {a} and {b} (on {counts.max()} faces or more) that "
            "splitting at its ends does not free; repair the mesh first"
        )
    if split.first_edge is not None:  # named by the input's vertex numbers
        split = dataclasses.replace(split, first_edge=tuple(int(used[k]) for k in split.first_edge))
    return vertices, split_faces, split


def _faces(n: int) -> str:
    return f"{n} face" if n == 1 else f"{n} faces"


def _connectivity(vertices: np.ndarray, faces: np.ndarray) -> tuple[bytes, np.ndarray, np.ndarray]:
    """The Draco stream of the faces, and the faces and positions in the decoder's vertex order.

    Draco renumbers the vertices (and may split a pinched vertex or an inconsistently oriented
    edge); its order does not depend on the positions' bits, so a fine encoding tells where
    each of the stream's vertices came from.
    """
    module = draco._module()

    def once(points: np.ndarray, bits: int):
        data = bytes(
            module.encode(
                points,
                faces.astype(np.uint32),
                quantization_bits=bits,
                compression_level=draco.COMPRESSION_LEVEL,
            )
        )
        decoded = module.decode(data)
        return (
            data,
            np.asarray(decoded.faces, np.int64).reshape(-1, 3),
            np.asarray(decoded.points, np.float64),
        )

    # Distinct carrier positions (Draco merges equal ones) that all quantize to 0 but the last:
    # their residuals cost almost nothing (fertility.off: 2.53 bits per vertex, 2.77 with the
    # mesh's own positions at 1 bit).
    carrier = np.zeros((len(vertices), 3))
    carrier[:, 0] = np.arange(len(vertices)) * 1e-7
    carrier[-1] = 1.0
    stream, carried, _ = once(carrier, CARRIER_BITS)
    # Each vertex's number written in its position (base 1024 over the three axes, exact at
    # ORDER_BITS bits): the decoded positions name the vertices even where the mesh has several
    # at one place (the copies of a split non-manifold vertex).
    index = np.arange(len(vertices))
    digits = np.column_stack([index % 1024, (index // 1024) % 1024, index // 1024**2]).astype(np.float64)
    _, ordered, points = once(digits, ORDER_BITS)
    source = np.rint(points) @ np.array([1, 1024, 1024**2])
    if (
        not np.array_equal(carried, ordered)
        or len(ordered) != len(faces)
        or not np.array_equal(np.sort(source), index)
    ):
        raise ValueError(
            "the mesh has faces that cannot be oriented consistently (a non-orientable surface, "
            "such as a Moebius strip); repair it first"
        )
    return stream, ordered, vertices[source.astype(np.int64)]


def faces_bytes(mesh) -> int:
    """Bytes of the Draco stream of a mesh's faces in its chart record (what the positions cannot have)."""
    import trimesh

    vertices, faces, _ = check_surface(mesh.vertices, mesh.faces)
    oriented = trimesh.Trimesh(vertices, faces, process=False)
    trimesh.repair.fix_winding(oriented)
    return len(_connectivity(vertices, np.asarray(oriented.faces, np.int64))[0])


def encode_charts(
    mesh,
    bits: float,
    *,
    size: int | None = None,
    transform: str = "bandelet",
    frames: bool = True,
    normal_weight: float = DEFAULT_NORMAL_WEIGHT,
    restore: bool = False,
    fallback: bool = True,
    layer: bool = True,
    max_memory: int = MAX_MEMORY,
) -> bytes:
    """Compress a mesh of any topology into a chart mesh record of about ``bits`` bits.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    bits : float
        Target size of the whole record, in bits (the file lands within 3 % below it).
    size : int, optional
        Side of the geometry image (even, 8 to 4096); default :func:`chart_side`.
    transform, frames, normal_weight, restore
        As :func:`bandelets.surfaces.codec.encode_mesh`.
    fallback : bool
        Store Draco's own file of the mesh instead (record variant :data:`DRACO_ONLY`) where it
        measures better at the same size (meshes up to :data:`TRIED_UP_TO` vertices).
    layer : bool
        Also try the image at part of the bits and a normal layer in the rest (record variant
        flag :data:`LAYER`), kept where it measures better.
    max_memory : int
        Refuse a mesh or an image whose coding needs more bytes.

    Raises
    ------
    ValueError
        A bad mesh (:func:`check_surface`), or a target below what the faces alone take.
    """
    import trimesh

    vertices, faces, _ = check_surface(mesh.vertices, mesh.faces)
    checks.check_memory(len(faces), max_memory)
    oriented = trimesh.Trimesh(vertices, faces, process=False)
    trimesh.repair.fix_winding(oriented)  # Edgebreaker needs consistently oriented faces
    faces_in = np.asarray(oriented.faces, np.int64)
    stream, faces, positions = _connectivity(vertices, faces_in)
    side = chart_side(len(positions)) if size is None else int(size)
    if not (8 <= side <= 4096 and side % 2 == 0):
        raise ValueError(f"the geometry image size must be even, from 8 to 4096, got {side}")
    prefix = MAGIC + bytes([RECORD_VERSION])
    head = varint(len(stream)) + stream
    image_bits = bits - 8 * (len(prefix) + 1 + len(head) + 4)
    if image_bits < 8 * (len(head) // 8 + 32):
        raise ValueError(
            f"a target of {bits / 8:.0f} bytes is too small for this mesh: its faces alone take "
            f"{len(head)} bytes, its positions at least {len(head) // 8 + 32} more"
        )
    options = EncodeOptions(
        kind="geometry-image",
        transform=transform,
        frames=frames,
        normal_weight=normal_weight,
        extension="symmetric",
        restore=restore,
        loop_filter=False,
        max_memory=max_memory,
    )
    tried = len(positions) <= TRIED_UP_TO
    trials = _Trials(faces, positions, options, image_bits, size is None, max_memory)
    # The cut into charts first, at the default side; then, without a side asked for, the side.
    best = max(
        (trials.attempt(variant, side) for variant in range(len(CHART_VARIANTS) if tried else 1)), key=_score
    )
    if tried and size is None:
        others = {int(np.clip(round(side * factor / 2.0) * 2, 8, 4096)) for factor in SIDE_FACTORS} - {side}
        best = max([best, *(trials.attempt(best[1], other) for other in sorted(others))], key=_score)
    if layer:  # the best cut and side again, part of the bits to a normal layer (measured against none)
        # The image has part of the bits: so also at the smaller side that suits fewer bits.
        cut, best_share = best[1] & ~LAYER, None
        sides = [best[3], int(max(8, round(best[3] * SIDE_FACTORS[0] / 2.0) * 2))] if tried else [best[3]]
        for side_tried in sides:
            for share in normallayer.IMAGE_SHARES if tried else normallayer.IMAGE_SHARES[1:2]:
                trial = trials.layered(cut, side_tried, share)
                best, best_share = (trial, share) if trial[0] > best[0] else (best, best_share)
        if tried and best_share is not None and not restore:  # and the image restored by the decoder
            best = max([best, trials.layered(cut, best[3], best_share, restored=True)], key=_score)
    if tried and fallback:
        best = max(
            [
                best,
                (*_draco_trial(vertices, faces_in, positions, faces, bits - 8 * (len(prefix) + 6 + 4)), 0),
            ],
            key=_score,
        )
    _, variant, coded, _ = best
    if variant == DRACO_ONLY:
        body = prefix + bytes([DRACO_ONLY]) + varint(len(coded)) + coded
        return body + zlib.crc32(body).to_bytes(4, "little")
    body = prefix + bytes([variant]) + head + coded
    return body + zlib.crc32(body).to_bytes(4, "little")


class _Trials:
    """The encoder's trials of a mesh's cuts into charts, image sides and normal layers, each
    coded and measured (:data:`TRIAL_SAMPLES`): ``(psnr, variant byte, payload, side)``."""

    def __init__(self, faces, positions, options, bits: float, fit_side: bool, max_memory: int):
        self.faces, self.positions, self.options, self.bits = faces, positions, options, bits
        self.fit_side, self.max_memory = fit_side, max_memory
        self.labels: dict = {}
        self.made: dict = {}

    def image(self, variant: int, side: int):
        """The side (grown to hold every chart unless a side was asked for), layout and image."""
        if variant not in self.labels:
            self.labels[variant] = charts.region_charts(self.faces, *CHART_VARIANTS[variant])
        if self.fit_side:  # many small charts (a soup of parts) need a larger image than the default
            side = fitting_side(self.labels[variant], self.faces, side)
        if (variant, side) not in self.made:
            layout = charts.layout(self.faces, self.labels[variant], side)
            owned = charts.owners(layout)
            points = self.positions[layout.corner_vertex[owned]]
            self.made[variant, side] = layout, atlas.fit(layout.pixels[owned], points, side)
        return side, *self.made[variant, side]

    def _read(self, coded: bytes, layout) -> np.ndarray:
        return _read_back(coded, layout, len(self.positions), self.max_memory)

    def attempt(self, variant: int, side: int) -> tuple[float, int, bytes, int]:
        """The image alone at all the bits."""
        side, layout, image = self.image(variant, side)
        coded = encode_with_stats(image, self.options, bpp=self.bits / (side * side)).data
        return _trial_psnr(self._read(coded, layout), self.faces, self.positions), variant, coded, side

    def layered(
        self, variant: int, side: int, share: float, restored: bool = False
    ) -> tuple[float, int, bytes, int]:
        """The image at ``share`` of the bits (``restored``: restored by the decoder, the iteration
        count the encoder's), a normal layer (:mod:`.normallayer`) in the rest; the payload: image
        length, image, step, layer (``-inf`` if no layer fits)."""
        side, layout, image = self.image(variant, side)
        options = dataclasses.replace(self.options, restore=True) if restored else self.options
        coded = encode_with_stats(image, options, bpp=share * self.bits / (side * side)).data
        read = self._read(coded, layout)
        normals, bend = normallayer.normal_curvature(read, self.faces)
        offsets = np.einsum("ij,ij->i", self.positions - read, normals)
        gain = float(np.float32(offsets @ bend / max(float(bend @ bend), 1e-300)))  # least squares
        head = varint(len(coded)) + coded
        scale = float(np.linalg.norm(np.ptp(self.positions, axis=0)))
        found = normallayer.encode(offsets - gain * bend, self.bits - 8 * (len(head) + 8), scale)
        if found is None:
            return -np.inf, variant | LAYER, b"", side
        step, data = found
        q = normallayer.decode(data, len(self.positions))
        psnr = _trial_psnr(normallayer.apply(read, self.faces, step, gain, q), self.faces, self.positions)
        return psnr, variant | LAYER, head + struct.pack("<ff", step, gain) + data, side


def _draco_trial(vertices, faces_in, positions, faces, bits: float) -> tuple[float, int, bytes]:
    """Draco's own file of the mesh within ``bits`` and its trial PSNR (``-inf`` if none fits)."""
    import trimesh

    from . import metrics

    try:
        data = draco.encode(trimesh.Trimesh(vertices, faces_in, process=False), bits / 8.0)
        decoded = draco.decode(data)
        psnr = metrics.hausdorff_psnr(
            trimesh.Trimesh(positions, faces, process=False), decoded, TRIAL_SAMPLES
        )
    except ValueError:
        return -np.inf, DRACO_ONLY, b""
    return psnr, DRACO_ONLY, data


def fitting_side(labels: np.ndarray, faces: np.ndarray, side: int) -> int:
    """The smallest side from ``side`` up (by quarters, even) whose image holds every chart."""
    n_vertices = int(faces.max()) + 1
    counts = np.bincount(np.unique(labels[:, None] * n_vertices + faces) // n_vertices)  # chart vertices
    while True:
        try:
            charts.pack(counts, side)
            return side
        except ValueError:
            if side >= 4096:
                raise
            side = min(4096, int(np.ceil(side * 1.25 / 2.0)) * 2)


def _score(trial: tuple[float, int, bytes]) -> float:
    return trial[0]


def _positions(image: np.ndarray, layout: charts.Layout, n_vertices: int) -> np.ndarray:
    """Every vertex read at its place in its first chart."""
    owned = charts.owners(layout)
    positions = np.zeros((n_vertices, 3))
    positions[layout.corner_vertex[owned]] = atlas.sample(image, layout.pixels[owned])
    return positions


def _read_back(coded: bytes, layout, n_vertices: int, max_memory: int) -> np.ndarray:
    """The positions the decoder reads from a coded image."""
    header, streams = unpack(coded)
    return _positions(decode_parsed(header, streams, max_memory=max_memory), layout, n_vertices)


def _trial_psnr(decoded: np.ndarray, faces: np.ndarray, positions: np.ndarray) -> float:
    """Hausdorff PSNR of decoded positions on the faces (:data:`TRIAL_SAMPLES` samples)."""
    import trimesh

    from . import metrics

    try:
        return metrics.hausdorff_psnr(
            trimesh.Trimesh(positions, faces, process=False),
            trimesh.Trimesh(decoded, faces, process=False),
            TRIAL_SAMPLES,
        )
    except ValueError:  # a decoded mesh of no area
        return -np.inf


def _parse(data: bytes) -> tuple[int, bytes, bytes]:
    """The variant byte, the Draco stream and the rest (the image) of a chart mesh record."""
    data = bytes(data)
    if len(data) < 10 or not is_chart_file(data):
        raise ValueError("not a chart mesh file")
    if zlib.crc32(data[:-4]) != int.from_bytes(data[-4:], "little"):
        raise ValueError("corrupt chart mesh file (CRC mismatch)")
    if data[4] not in (1, RECORD_VERSION):
        raise ValueError(
            f"chart mesh record version {data[4]}; this build reads versions 1 to {RECORD_VERSION}"
        )
    variant = data[5]
    layered = data[4] >= 2 and variant != DRACO_ONLY and variant & LAYER
    if variant != DRACO_ONLY and (variant & ~LAYER if layered else variant) >= len(CHART_VARIANTS):
        raise ValueError(f"corrupt chart mesh file (chart variant {variant})")
    length, offset = read_varint(data, 6, what="not a chart mesh file")
    if offset + length > len(data) - 4:
        raise ValueError("truncated chart mesh file")
    return variant, data[offset : offset + length], data[offset + length : -4]


def _faces_stream(stream: bytes):
    try:
        return draco._module().decode(stream)
    except Exception as err:  # DracoPy raises its own error types
        raise ValueError(f"corrupt chart mesh file (faces: {err})") from None


def describe(data: bytes) -> dict:
    """What a chart mesh record holds, without decoding its image (``bandelets info``).

    Returns
    -------
    dict
        ``representation``: ``"multi-chart geometry image"``, or ``"draco"`` where the record
        holds Draco's own file of the mesh (the encoder found it better at the asked size);
        ``vertices``, ``faces``, ``bytes``, ``faces_bytes`` (the Draco stream) and, for an
        image, ``charts`` (faces per seed, merged), ``side`` and ``image_bytes``.
    """
    variant, stream, image_data = _parse(data)
    decoded = _faces_stream(stream)
    info = {
        "representation": "draco" if variant == DRACO_ONLY else "multi-chart geometry image",
        "vertices": len(np.asarray(decoded.points).reshape(-1, 3)),
        "faces": len(np.asarray(decoded.faces).reshape(-1, 3)),
        "bytes": len(data),
        "faces_bytes": len(stream),
    }
    if variant != DRACO_ONLY:
        image_data, _, layer = _layer_parts(variant, image_data)
        header, _ = unpack(image_data)
        per_seed, merged = CHART_VARIANTS[variant & ~LAYER]
        info |= {
            "charts": {"faces_per_seed": per_seed, "merged": merged},
            "side": header.width,
            "image_bytes": len(image_data),
            "normal_layer_bytes": 0 if layer is None else len(layer),
        }
    return info


def decode_charts(data: bytes, max_memory: int = MAX_MEMORY):
    """Rebuild the mesh of a chart mesh record (:func:`encode_charts`).

    Returns
    -------
    trimesh.Trimesh
        The input's faces (in Draco's vertex order) and decoded positions.

    Raises
    ------
    ValueError
        A corrupt or truncated record.
    """
    import trimesh

    variant, stream, image_data = _parse(data)
    decoded = _faces_stream(stream)
    faces = np.asarray(decoded.faces, np.int64).reshape(-1, 3)
    n_vertices = len(np.asarray(decoded.points).reshape(-1, 3))
    if len(faces) == 0 or faces.max() >= n_vertices or np.unique(faces).size != n_vertices:
        raise ValueError("corrupt chart mesh file (faces)")
    if variant == DRACO_ONLY:  # the positions are Draco's own
        if image_data:
            raise ValueError("corrupt chart mesh file (bytes after the Draco stream)")
        return trimesh.Trimesh(np.asarray(decoded.points, np.float64).reshape(-1, 3), faces, process=False)
    image_data, (step, gain), layer = _layer_parts(variant, image_data)
    header, streams = unpack(image_data)
    if header.kind != "geometry-image" or header.height != header.width or header.width % 2:
        raise ValueError("corrupt chart mesh file (not a square geometry image)")
    checks.check_memory(len(faces), max_memory)
    image = decode_parsed(header, streams, max_memory=max_memory)
    cut = CHART_VARIANTS[variant & ~LAYER]
    layout = charts.layout(faces, charts.region_charts(faces, *cut), header.width)
    positions = _positions(image, layout, n_vertices)
    if layer is not None:
        positions = normallayer.apply(positions, faces, step, gain, normallayer.decode(layer, n_vertices))
    return trimesh.Trimesh(positions, faces, process=False)


def _layer_parts(variant: int, image_data: bytes) -> tuple[bytes, tuple[float, float], bytes | None]:
    """The image, the step and gain and the normal layer of a record's payload (no layer: ``None``)."""
    if not variant & LAYER:
        return image_data, (0.0, 0.0), None
    length, offset = read_varint(image_data, 0, what="not a chart mesh file")
    if offset + length + 8 > len(image_data):
        raise ValueError("truncated chart mesh file")
    step, gain = struct.unpack("<ff", image_data[offset + length : offset + length + 8])
    if not (np.isfinite(step) and step > 0 and np.isfinite(gain)):
        raise ValueError("corrupt chart mesh file (normal layer step or gain)")
    return image_data[offset : offset + length], (float(step), float(gain)), image_data[offset + length + 8 :]
