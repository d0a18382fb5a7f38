"""Mesh coding: a closed genus-0 mesh -> spherical geometry image -> .bdl, and back.

The .bdl file is an ordinary geometry-image file (kind ``geometry-image``, three channels
of positions in the mesh's unit): its header already holds the image size, which is all
the decoder needs to rebuild the glued mesh (:func:`.geometry_image.mesh_from_image`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import checks, geometry_image, sphere

__all__ = [
    "GeometryImage",
    "MESH_FORMATS",
    "decode_mesh",
    "encode_mesh",
    "load_mesh",
    "make_geometry_image",
    "mesh_bytes",
]

MESH_FORMATS = ("obj", "ply", "off")


def load_mesh(path: str | os.PathLike):
    """Read a triangle mesh (OBJ, PLY, OFF, STL, ... through trimesh), duplicate vertices merged.

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
        mesh = trimesh.load(path, force="mesh", process=True)
    except Exception as err:  # trimesh raises many error types for bad files
        raise ValueError(f"{path}: not a readable mesh ({err})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{path}: no triangles found")
    return mesh


def mesh_bytes(mesh, file_type: str) -> bytes:
    """The mesh as an OBJ, PLY or OFF file."""
    if file_type not in MESH_FORMATS:
        raise ValueError(f"unsupported mesh format {file_type!r}; use one of {', '.join(MESH_FORMATS)}")
    data = mesh.export(file_type=file_type)
    return data.encode() if isinstance(data, str) else data


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
        :func:`.sphere.area_distortion` of the spherical parameterization.
    """

    positions: np.ndarray
    normals: np.ndarray
    distortion: dict


def make_geometry_image(mesh, size: int = 256, **relaxation) -> GeometryImage:
    """Check, parameterize on the sphere and sample a closed genus-0 mesh.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    size : int
        Side ``n`` of the image, even, 4 to 4096.
    **relaxation
        ``max_steps`` and ``tol`` of :func:`.sphere.spherical_parameterization`.

    Raises
    ------
    ValueError
        Bad size, or a mesh that is not closed, manifold, connected and of genus 0.
    """
    if not (4 <= size <= 4096 and size % 2 == 0):
        raise ValueError(f"the geometry image size must be even, from 4 to 4096, got {size}")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    checks.check_genus0(vertices, faces)
    if mesh.volume < 0:  # the faces must face outwards
        faces = faces[:, ::-1]
        mesh = mesh.copy()
        mesh.invert()
    mapped = sphere.spherical_parameterization(vertices, faces, **relaxation)
    positions, normals = geometry_image.sample(
        vertices, faces, mapped.points, size, np.asarray(mesh.vertex_normals, dtype=np.float64)
    )
    return GeometryImage(positions, normals, mapped.distortion)


def encode_mesh(
    mesh,
    *,
    size: int = 256,
    bpp: float | None = None,
    bits_per_vertex: float | None = None,
    n_bytes: int | None = None,
    transform: str = "bandelet",
    frames: bool = True,
    normal_weight: float = 2.0,
    extension: str = "spherical",
    image: np.ndarray | None = None,
) -> bytes:
    """Compress a closed genus-0 mesh into a .bdl file.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    size : int
        Side of the geometry image (even).
    bpp, bits_per_vertex, n_bytes : at most one
        Target: bits per geometry-image pixel, bits per vertex of ``mesh``, or bytes of the
        whole file; the file lands within 3 % below it. Default: 1 bpp.
    transform : {"bandelet", "wavelet"}
    frames, normal_weight, extension
        Local frames, weight of their normal component and wavelet boundary extension
        (:func:`bandelets.encode`); the defaults are the best measured (benchmarks/rd_meshes.py).
    image : ndarray of float, shape (size, size, 3), optional
        The geometry image of ``mesh`` if already made (:func:`make_geometry_image`).

    Returns
    -------
    bytes
    """
    from .. import codec

    targets = {"bpp": bpp, "bits_per_vertex": bits_per_vertex, "n_bytes": n_bytes}
    given = [name for name, value in targets.items() if value is not None]
    if len(given) > 1:
        raise ValueError(f"give at most one target, got {', '.join(given)}")
    codec.check_geometry_options(normal_weight, extension)  # before the slow parameterization
    if image is None:
        image = make_geometry_image(mesh, size).positions
    pixels = image.shape[0] * image.shape[1]
    for name, value in targets.items():
        if value is not None and not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive number, got {value}")
    if bits_per_vertex is not None:
        bpp = bits_per_vertex * len(mesh.vertices) / pixels
    elif n_bytes is not None:
        bpp = 8.0 * n_bytes / pixels
    return codec.encode(
        image,
        bpp=1.0 if bpp is None else bpp,
        transform=transform,
        kind="geometry-image",
        frames=frames,
        normal_weight=normal_weight,
        extension=extension,
    )


def decode_mesh(data: bytes):
    """Rebuild the closed mesh of a geometry-image .bdl file.

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    ValueError
        A corrupt file (``bandelets.FormatError``), or one that is not a square geometry image
        of even side.
    """
    from .. import codec
    from ..bitstream import unpack

    header, streams = unpack(bytes(data))
    if header.kind != "geometry-image" or header.height != header.width or header.width % 2:
        raise ValueError(
            f"not a mesh file: a {header.width} x {header.height} {header.kind} "
            "(expected a square geometry image of even side)"
        )
    return geometry_image.mesh_from_image(codec.decode_parsed(header, streams))
