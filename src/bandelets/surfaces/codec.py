"""Mesh coding: a closed genus-0 mesh -> spherical geometry image -> .bdl, and back.

Any other mesh (open, of higher genus, of several components) takes the multi-chart route of
:mod:`.chartcodec`: :func:`encode_mesh` chooses by :func:`.checks.check_genus0`, and
:func:`decode_mesh` by the file's magic (``b"BDLC"``, a mesh record of its own; see there).

The .bdl file is an ordinary geometry-image file (kind ``geometry-image``, three channels
of positions in the mesh's unit): its header holds the image size, which is all the decoder
needs to rebuild the glued mesh (:func:`.geometry_image.mesh_from_image`), and the vertex
count of the original mesh, down to which the decoder simplifies that mesh by default
(:func:`.geometry_image.decimate`): a 6,000-vertex input does not come back with 262,144.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..codec.decoder import decode_parsed
from ..codec.encoder import encode_with_stats
from ..codec.options import EncodeOptions
from ..format.fields import DEFAULT_NORMAL_WEIGHT, MAX_MEMORY
from ..format.header import unpack
from . import checks, geometry_image, sphere

__all__ = [
    "AUTO_SIZES",
    "DEFAULT_SIZE",
    "GeometryImage",
    "is_genus0",
    "SphericalMesh",
    "auto_size",
    "check_mesh_memory",
    "check_size",
    "MESH_FORMATS",
    "OVERSAMPLING",
    "DECIMATED_PIXELS",
    "decode_mesh",
    "encode_mesh",
    "load_mesh",
    "make_geometry_image",
    "map_to_sphere",
    "mesh_bytes",
    "sample_geometry_image",
]

MESH_FORMATS = ("obj", "ply", "off")


def load_mesh(path: str | os.PathLike):
    """Read a triangle mesh (OBJ, PLY, OFF, STL, ... through trimesh).

    A mesh that is closed and of genus 0 as stored (:func:`bandelets.surfaces.checks.check_genus0`)
    is kept as it is; any other has its coincident vertices merged (a triangle soup, as STL
    stores, becomes a surface). Merging first would glue distinct vertices that happen to
    coincide (``cow.off``) into a non-manifold edge.

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    ValueError
        Missing or unreadable file, or no triangles in it.
    """
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except ImportError:  # an optional dependency trimesh tries for text it cannot decode
        raise ValueError(f"{path}: not a readable mesh (neither binary nor text)") from None
    except Exception as err:  # trimesh raises many error types for bad files
        raise ValueError(f"{path}: not a readable mesh ({err})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{path}: no triangles found")
    bad = np.flatnonzero(~np.all(np.isfinite(mesh.vertices), axis=1))
    if bad.size:  # before trimesh's processing drops them and their faces silently
        raise ValueError(f"{path}: vertex {bad[0]} has a non-finite coordinate (NaN or infinity)")
    try:
        checks.check_genus0(mesh.vertices, mesh.faces)
        return mesh
    except ValueError:
        return trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)


def mesh_bytes(mesh, file_type: str) -> bytes:
    """The mesh as an OBJ, PLY or OFF file."""
    if file_type not in MESH_FORMATS:
        raise ValueError(f"unsupported mesh format {file_type!r}; use one of {', '.join(MESH_FORMATS)}")
    data = mesh.export(file_type=file_type)
    return data.encode() if isinstance(data, str) else data


#: Side of the geometry image when the target is in bits per pixel (or absent).
DEFAULT_SIZE = 256
#: Sides the coder chooses from for a target in bytes or bits per vertex, and the fewest bits
#: per pixel it lets the chosen side have. A larger image has a higher ceiling (the remeshing
#: error) but fewer bits per pixel; on fandisk, elephant, the horse and the knight the larger
#: of two sides measured at least as well down to about 0.1 bit per pixel, within 0.5 dB
#: either way at the crossing (closing note of issue #4, benchmarks/rd-meshes-results.md).
AUTO_SIZES = (64, 128, 256, 512, 1024)
MIN_AUTO_BPP = 0.1


def auto_size(bits: float) -> int:
    """Side of the geometry image for a file of ``bits`` bits.

    The largest of :data:`AUTO_SIZES` that still gets :data:`MIN_AUTO_BPP` bits per pixel,
    the smallest if none does.
    """
    fitting = [n for n in AUTO_SIZES if bits >= MIN_AUTO_BPP * n * n]
    return fitting[-1] if fitting else AUTO_SIZES[0]


def check_size(size: int) -> None:
    """``ValueError`` unless ``size`` is a usable geometry-image side (even, 4 to 4096)."""
    if not (isinstance(size, (int, np.integer)) and 4 <= size <= 4096 and size % 2 == 0):
        raise ValueError(f"the geometry image size must be even, from 4 to 4096, got {size}")


@dataclass(frozen=True)
class SphericalMesh:
    """A checked closed genus-0 mesh and its spherical parameterization, from which
    geometry images of any size are sampled.

    Attributes
    ----------
    vertices : ndarray of float, shape (V, 3)
    faces : ndarray of int, shape (F, 3)
        Facing outwards.
    points : ndarray of float, shape (V, 3)
        Each vertex's point on the unit sphere.
    normals : ndarray of float, shape (V, 3)
        Unit vertex normals.
    distortion : dict
        :func:`.stretch.area_distortion` of the parameterization.
    """

    vertices: np.ndarray
    faces: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    distortion: dict


@dataclass(frozen=True)
class GeometryImage:
    """A mesh resampled on the octahedral grid.

    Attributes
    ----------
    positions : ndarray of float, shape (n, n, 3)
        Surface points, in the mesh's unit.
    normals : ndarray of float, shape (n, n, 3)
        Unit normals (vertex normals interpolated) at the same points.
    distortion : dict
        :func:`.stretch.area_distortion` of the spherical parameterization.
    """

    positions: np.ndarray
    normals: np.ndarray
    distortion: dict


def map_to_sphere(mesh, max_memory: int = MAX_MEMORY, **relaxation) -> SphericalMesh:
    """Check a mesh (closed, manifold, connected, genus 0) and parameterize it on the sphere.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    max_memory : int
        Refuse a mesh whose parameterization needs more bytes (:func:`.checks.check_memory`).
    **relaxation
        ``max_steps`` and ``tol`` of :func:`.sphere.spherical_parameterization`.

    Raises
    ------
    ValueError
        A mesh that is not closed, manifold, connected and of genus 0, or too large.
    """
    checks.check_memory(len(mesh.faces), max_memory)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    checks.check_genus0(vertices, faces)
    if mesh.volume < 0:  # the faces must face outwards
        faces = faces[:, ::-1]
        mesh = mesh.copy()
        mesh.invert()
    mapped = sphere.spherical_parameterization(vertices, faces, **relaxation)
    normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
    return SphericalMesh(vertices, faces, mapped.points, normals, mapped.distortion)


def sample_geometry_image(spherical: SphericalMesh, size: int) -> GeometryImage:
    """The ``size x size`` geometry image (positions and normals) of a parameterized mesh."""
    check_size(size)
    positions, normals = geometry_image.sample(
        spherical.vertices, spherical.faces, spherical.points, size, spherical.normals
    )
    return GeometryImage(positions, normals, spherical.distortion)


def make_geometry_image(
    mesh, size: int = DEFAULT_SIZE, max_memory: int = MAX_MEMORY, **relaxation
) -> GeometryImage:
    """Check, parameterize on the sphere and sample a closed genus-0 mesh.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    size : int
        Side ``n`` of the image, even, 4 to 4096.
    max_memory : int
        Refuse a mesh whose parameterization needs more bytes (:func:`.checks.check_memory`).
    **relaxation
        ``max_steps`` and ``tol`` of :func:`.sphere.spherical_parameterization`.

    Raises
    ------
    ValueError
        Bad size, or a mesh that is not closed, manifold, connected and of genus 0, or too large.
    """
    check_size(size)  # before the slow parameterization
    return sample_geometry_image(map_to_sphere(mesh, max_memory, **relaxation), size)


def encode_mesh(
    mesh,
    *,
    size: int | None = None,
    bpp: float | None = None,
    bits_per_vertex: float | None = None,
    n_bytes: int | None = None,
    transform: str = "bandelet",
    frames: bool = True,
    normal_weight: float = DEFAULT_NORMAL_WEIGHT,
    extension: str = "spherical",
    restore: bool = False,
    image: np.ndarray | None = None,
    spherical: SphericalMesh | None = None,
    max_memory: int = MAX_MEMORY,
) -> bytes:
    """Compress a mesh into a .bdl file: a closed genus-0 mesh as a spherical geometry image,
    any other as a multi-chart one (:func:`.chartcodec.encode_charts`: ``size`` is then the side
    of that image, ``bpp`` its bits per pixel; ``extension``, ``image`` and ``spherical`` do
    not apply).

    Parameters
    ----------
    mesh : trimesh.Trimesh
    size : int, optional
        Side of the geometry image (even). Default: :func:`auto_size` of the target for a
        target in bytes or bits per vertex, :data:`DEFAULT_SIZE` otherwise.
    bpp, bits_per_vertex, n_bytes : at most one
        Target: bits per geometry-image pixel, bits per vertex of ``mesh``, or bytes of the
        whole file; the file lands within 3 % below it. Default: 1 bpp.
    transform : {"bandelet", "wavelet"}
    frames, normal_weight, extension
        Local frames, weight of their normal component and wavelet boundary extension
        (:func:`bandelets.encode`); the defaults are the best measured (benchmarks/rd_meshes.py).
    restore : bool
        Let the decoder restore the image (:mod:`bandelets.restore.restoration`). Off by default: the
        encoder picks the iteration count that lowers the L2 error of the positions, which
        helps the Hausdorff PSNR of CAD meshes (fandisk +1.3 dB BD, up to +2.2 dB at 8 b/v) but
        slides the points of scanned ones along their surface (bunny -0.2 dB): variants
        ``default,restored`` of benchmarks/rd_meshes.py. No loop filter
        (:mod:`bandelets.restore.loopfilter`) either way: not measured on the Hausdorff PSNR yet.
    image : ndarray of float, shape (n, n, 3), optional
        The geometry image to code, if already made (:func:`make_geometry_image`); it fixes
        the size.
    spherical : SphericalMesh, optional
        The parameterization of ``mesh``, if already made (:func:`map_to_sphere`).
    max_memory : int
        Refuse (``ValueError``) a mesh whose parameterization, an image whose encoding, or a
        decoded mesh whose rebuilding (:func:`check_mesh_memory`) needs more bytes.

    Returns
    -------
    bytes
    """
    targets = {"bpp": bpp, "bits_per_vertex": bits_per_vertex, "n_bytes": n_bytes}
    given = [name for name, value in targets.items() if value is not None]
    if len(given) > 1:
        raise ValueError(f"give at most one target, got {', '.join(given)}")
    for name, value in targets.items():
        if value is not None and not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive number, got {value}")
    by_charts = image is None and spherical is None and not is_genus0(mesh)
    if by_charts:
        from .chartcodec import check_surface

        check_surface(mesh.vertices, mesh.faces)  # a bad mesh's own error, before the options'
    options = EncodeOptions(  # validated before the slow parameterization
        kind="geometry-image",
        transform=transform,
        frames=frames,
        normal_weight=normal_weight,
        extension=extension,
        restore=restore,
        loop_filter=False,
        max_memory=max_memory,
        mesh_vertices=min(len(mesh.vertices), 2**32 - 1),
    )
    if image is not None:
        if size is not None and size != image.shape[0]:
            raise ValueError(f"size {size} given with a {image.shape[0]} x {image.shape[1]} geometry image")
        size = image.shape[0]
    asked_size = size
    if bits_per_vertex is not None:
        bits = bits_per_vertex * len(mesh.vertices)
    elif n_bytes is not None:
        bits = 8.0 * n_bytes
    else:
        size = size or DEFAULT_SIZE
        bits = (1.0 if bpp is None else bpp) * size * size
    if by_charts:
        from .chartcodec import chart_side, encode_charts  # any other topology: multi-chart images

        if bits_per_vertex is None and n_bytes is None:  # bits per pixel of the chart image
            size = asked_size or chart_side(len(mesh.vertices))
            bits = (1.0 if bpp is None else bpp) * size * size
        chosen = {"transform": transform, "frames": frames, "normal_weight": normal_weight}
        chosen |= {"restore": restore, "max_memory": max_memory}
        return _parts_or(mesh, bits, lambda: encode_charts(mesh, bits, size=size, **chosen), chosen)
    size = size or auto_size(bits)
    check_size(size)
    check_mesh_memory(size, max_memory)  # the decoder's limit
    if image is None:
        image = sample_geometry_image(spherical or map_to_sphere(mesh, max_memory), size).positions
    return encode_with_stats(image, options, bpp=bits / (image.shape[0] * image.shape[1])).data


#: Below this many bits per vertex, a mesh whose every component is a closed genus-0 part takes
#: the record of parts without the chart route coded for the comparison (:func:`_parts_or`).
RECORD_ALONE_BELOW = 5.0


def _parts_or(mesh, bits: float, charted: Callable[[], bytes], chosen: dict) -> bytes:
    """The chart route's file (``charted()``), or a record of parts (:mod:`.parts`: the closed
    genus-0 components each on the spherical path, the rest on the chart route) where the mesh has
    such components and the record measures better (Hausdorff PSNR,
    :data:`.chartcodec.TRIAL_SAMPLES`), or without the comparison when every component is such a
    part and the target is below :data:`RECORD_ALONE_BELOW` bits per vertex.

    The chart route coded for the comparison doubled the encode time. With no rest it loses at low
    rates: the two spheres and the bunny with the fandisk of benchmarks/mesh_topology.py at Draco's
    two smallest files (3.7 to 5.9 bits per vertex), by 2.6 to 13.9 dB; two icospheres (1,284 and
    5,124 vertices) at 4 and 5 bits per vertex, by 0.7 to 3.6 dB. At higher rates the spherical
    path's resampling caps the record, and the chart route keeps the input's vertices: on the
    icospheres it leads the record by 2.0 and 2.2 dB at 6 bits per vertex, 5.9 to 17.8 dB at 8 and
    16. A rest can tip it at any rate (a bumpy sphere beside a small cut one at 4 bits per vertex: the
    rest's share left it at 49.6 dB, the chart route's file measured 6 dB above the record).
    """
    from . import parts
    from .chartcodec import TRIAL_SAMPLES, check_surface, faces_bytes

    vertices, faces, _ = check_surface(mesh.vertices, mesh.faces)
    pieces = parts.split(vertices, faces)
    if pieces is None:
        return charted()
    try:  # the rest's faces, and the least its positions take beside them (chartcodec.encode_charts)
        fixed = [0 if is_genus0(piece) else faces_bytes(piece) * 9 // 8 + 48 for piece in pieces]
        record = parts.encode_parts(
            pieces, bits, lambda part, n: encode_mesh(part, n_bytes=n, **chosen), fixed
        )
    except ValueError:  # a part's share too small for its faces, a rest of a single triangle
        return charted()
    if not any(fixed) and bits < RECORD_ALONE_BELOW * len(vertices):
        return record
    return parts.better(mesh, [charted(), record], decode_mesh, TRIAL_SAMPLES)


def is_genus0(mesh) -> bool:
    """Whether the spherical path takes ``mesh`` (closed, manifold, connected, genus 0)."""
    try:
        checks.check_genus0(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64))
    except ValueError:
        return False
    return True


def decode_mesh(data: bytes, vertices: int | str | None = None, max_memory: int = MAX_MEMORY):
    """Rebuild the mesh of a mesh .bdl file (a multi-chart file: the input's faces, whatever
    ``vertices`` asks, :func:`.chartcodec.decode_charts`; a record of parts, :mod:`.parts`: each
    part with its own vertex count, whatever ``vertices`` asks).

    Parameters
    ----------
    data : bytes
    vertices : int, "full" or None
        Vertex count of the mesh returned: the glued mesh of the whole image (``n^2`` vertices)
        is simplified down to it by quadric edge collapse (:func:`.geometry_image.decimate`;
        seconds for a 512 x 512 image). ``None``: the vertex count of the original mesh, which
        the file holds (the whole grid for a file without one); ``"full"``: the whole grid.

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    ValueError
        A corrupt file (``bandelets.FormatError``), one that is not a square geometry image
        of even side, a mesh whose rebuilding and writing would need more than ``max_memory``
        bytes (:func:`check_mesh_memory`), or ``vertices`` below 4.
    """
    if not (vertices is None or vertices == "full" or isinstance(vertices, (int, np.integer))):
        raise ValueError(f"vertices must be a count, 'full' or None, got {vertices!r}")
    if isinstance(vertices, (int, np.integer)) and vertices < 4:
        raise ValueError(f"a closed mesh has at least 4 vertices, asked for {vertices}")
    from . import parts
    from .chartcodec import decode_charts, is_chart_file

    if is_chart_file(data):  # the input's faces come back: no simplification
        return decode_charts(data, max_memory)
    if parts.is_parts_file(data):  # each part as its own file says, one after the other
        inner = parts.files(data)
        if any(parts.is_parts_file(one) for one in inner):
            raise ValueError("corrupt parts mesh file (a record of parts inside one)")
        return parts.join([decode_mesh(one, None, max_memory) for one in inner])
    header, streams = unpack(bytes(data))
    if header.kind != "geometry-image" or header.height != header.width or header.width % 2:
        raise ValueError(
            f"not a mesh file: a {header.width} x {header.height} {header.kind} "
            "(expected a square geometry image of even side)"
        )
    check_mesh_memory(header.width, max_memory)
    image = decode_parsed(header, streams, max_memory=max_memory)
    if vertices is None:
        vertices = header.mesh_vertices or "full"
    if vertices == "full":
        return geometry_image.mesh_from_image(image)
    # Quadric decimation keeps what matters of a grid with OVERSAMPLING times the vertices; a
    # denser one, or one above DECIMATED_PIXELS, is halved first, to bound the time.
    image = geometry_image.coarsen(image, OVERSAMPLING * int(vertices), DECIMATED_PIXELS)
    check_mesh_memory(image.shape[0], max_memory, DECIMATION_BYTES_PER_PIXEL)
    return geometry_image.decimate(geometry_image.mesh_from_image(image), int(vertices))


#: Fewest grid vertices per decoded vertex before decimation (:func:`.geometry_image.coarsen`):
#: a 1024 x 1024 image decoded to 8,000 vertices is decimated from 512 x 512, one of 512 x 512
#: from itself. The time against the PSNR: arm.obj at 16 bits per vertex (1024 x 1024) to its
#: 8,311 vertices, 7.5 s and 77.85 dB from 512 x 512, 37 s and 79.73 dB from 1024 x 1024
#: (the full grid: 80.88 dB); from 256 x 256 at 8 bits per vertex, 70.24 dB against 74.86.
OVERSAMPLING = 16
#: Most pixels of the grid that is decimated, whatever the vertex count asked for: the time of the
#: quadric decimation grows with the grid, not the target. A 55,730-vertex mesh coded at 4 bits per
#: vertex (a 1024 x 1024 image) took 99 s to decode from its 1024 x 1024 grid (83.5 dB) on the shared
#: 2-core machine; from 512 x 512, see BENCHMARKS.md (benchmarks/mesh_pipeline.py).
DECIMATED_PIXELS = 512 * 512


#: Peak bytes per pixel of a geometry image rebuilt into a mesh and written to a file (peak
#: resident memory at 1024 x 1024: 548 B/pixel written as OBJ, 269 as PLY), rounded up.
MESH_BYTES_PER_PIXEL = 640
#: The same for a mesh decimated before it is written (peak resident memory decimating a 1024 x
#: 1024 grid to 8,000 vertices and writing them as OBJ, the interpreter included: 1207 B/pixel).
DECIMATION_BYTES_PER_PIXEL = 1280


def check_mesh_memory(side: int, max_memory: int = MAX_MEMORY, per_pixel: int = MESH_BYTES_PER_PIXEL) -> None:
    """``ValueError`` if the mesh of a ``side x side`` geometry image needs more than ``max_memory``
    bytes to rebuild (and decimate) and write (``per_pixel`` bytes a pixel, by default
    :data:`MESH_BYTES_PER_PIXEL`: 1,830 pixels a side with the default ``max_memory``)."""
    need = per_pixel * side * side
    if need > max_memory:
        raise ValueError(
            f"a mesh of {side} x {side} vertices needs about {need / 2**20:.0f} MiB to rebuild and write, "
            f"above the limit of {max_memory / 2**20:.0f} MiB (max_memory)"
        )
