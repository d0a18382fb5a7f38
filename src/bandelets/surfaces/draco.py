"""Google's Draco (through DracoPy) as the mesh anchor of ``bandelets rd``.

Draco codes the mesh itself: its connectivity (Edgebreaker) and its vertex positions
quantized on a uniform grid of ``2**bits`` steps along the longest side of the bounding box,
then predicted (parallelogram) and entropy coded. The only quality knob is ``bits``;
:func:`encode` takes the largest number of bits whose file fits the target size, at Draco's
strongest compression level (10). DracoPy is imported only here, when a file is made.
"""

from __future__ import annotations

import numpy as np

__all__ = ["COMPRESSION_LEVEL", "available", "decode", "encode", "version"]

COMPRESSION_LEVEL = 10  # Draco's slowest, smallest setting (its default is 7)
# Bits per coordinate tried. Draco takes up to 30, but at its level 10 its memory doubles with
# every bit past about 20 (gigabytes at 26), where the error is already a millionth of the box.
_BITS = (1, 20)


def available() -> bool:
    """Whether DracoPy can be imported."""
    try:
        import DracoPy  # noqa: F401
    except ImportError:
        return False
    return True


def _module():
    try:
        import DracoPy
    except ImportError:
        raise ValueError("the draco codec needs DracoPy (pip install DracoPy)") from None
    return DracoPy


def version() -> str:
    """DracoPy's version and the Draco bitstream version of the files it writes."""
    from importlib.metadata import version as package_version

    tetrahedron = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    header = _module().encode(tetrahedron, faces)
    # A Draco file starts with "DRACO", then the major and minor version of its bitstream.
    return f"DracoPy {package_version('DracoPy')}, Draco bitstream {header[5]}.{header[6]}"


def _encode_once(vertices: np.ndarray, faces: np.ndarray, bits: int) -> bytes:
    return bytes(
        _module().encode(vertices, faces, quantization_bits=bits, compression_level=COMPRESSION_LEVEL)
    )


def encode(mesh, n_bytes: float) -> bytes:
    """The Draco file of ``mesh`` with the most quantization bits that fits in ``n_bytes``.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    n_bytes : float
        Most bytes of the whole file.

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        DracoPy missing, or even one bit per coordinate exceeds the target (the
        connectivity alone costs about 2 bits per vertex).
    """
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.uint32)
    low, high = _BITS[0] - 1, _BITS[1] + 1  # the file grows with the bits: bisect on them
    best = b""
    while high - low > 1:
        bits = (low + high) // 2
        data = _encode_once(vertices, faces, bits)
        if len(data) <= n_bytes:
            best, low = data, bits
        else:
            high = bits
    if not best:
        raise ValueError(f"draco cannot fit this mesh in {n_bytes:.0f} bytes")
    return best


def decode(data: bytes):
    """The mesh of a Draco file, as ``trimesh.Trimesh`` (vertices in Draco's order).

    Raises
    ------
    ValueError
        DracoPy missing, or not a Draco mesh file.
    """
    import trimesh

    module = _module()
    try:
        decoded = module.decode(bytes(data))
    except Exception as err:  # DracoPy raises its own error types
        raise ValueError(f"not a Draco mesh file ({err})") from None
    faces = np.asarray(getattr(decoded, "faces", np.empty((0, 3))), dtype=np.int64).reshape(-1, 3)
    if faces.size == 0:
        raise ValueError("not a Draco mesh file (no faces)")
    return trimesh.Trimesh(np.asarray(decoded.points, dtype=np.float64), faces, process=False)
