"""Normal maps for the GPU: a renormalised mip chain, BC5 / BC7 / RGBA8 blocks, KTX2 and DDS files.

The pieces, each usable alone:

- :func:`mip_chain`: every mip level of a normal map down to 1 x 1, each level the area average of
  the base level's unit vectors over its footprint (2^k x 2^k texels at level k when the size is a
  power of two), renormalised to unit length (basisu's ``-renorm``). Odd sizes follow the GPU rule
  (level k is max(1, floor(n / 2^k)) texels wide) and the average weighs each texel by the part of
  it a coarser texel covers, so no row or column is dropped.
- :func:`flip_green`: the green-channel convention, OpenGL "up" <-> DirectX "down" (y negated).
- :func:`compress` / :func:`decode_blocks`: one level to blocks and back. BC5 holds x and y
  (z = sqrt(1 - x^2 - y^2) in the shader), BC7 and RGBA8 hold x, y, z; all UNORM, v -> (v + 1) / 2.
- :func:`angular_error_added`: the mean and 99th-percentile angle (degrees) the block format adds
  to the map it was made from.
- :func:`write_ktx2` / :func:`write_dds`: the containers, and :func:`export` for the whole path.

Libraries, and what is written here by hand:

- BC5 by ``quicktex`` (Apache-2.0): its BC4 endpoint search adds 0.46 degree on average to the
  flight-helmet leather map where etcpak's fast BC4 adds 0.74, and on a smooth map 0.007 where
  etcpak adds 0.40 (etcpak rounds endpoints coarsely on flat blocks).
- BC7 by ``etcpak`` (MIT), which wraps Rich Geldreich's bc7enc; quicktex has no BC7.
- Decoding by ``texture2ddecoder`` (MIT): etcpak 0.9.15's own ``decompress_bc5`` / ``_bc7`` crash
  (a segmentation fault and a MemoryError on a 12 x 8 image), so the check of what the blocks say
  goes through a decoder that neither encoder shares.
- KTX2 and DDS are written here to their specifications (the KTX 2.0 specification with the
  Khronos Data Format Specification 1.3 for the DFD; Microsoft's DDS_HEADER and DDS_HEADER_DXT10):
  libktx's binding ``pyktx`` ships only as a source package that needs the libktx C library and
  its version in the environment (``LIBKTX_VERSION``), and neither is on PyPI or in Debian; Pillow
  writes DDS but one level only. Both containers are small fixed headers.

This module imports numpy only; the three libraries are imported when a format needs them.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np

__all__ = [
    "FORMATS",
    "Export",
    "angular_error_added",
    "compress",
    "decode_blocks",
    "export",
    "flip_green",
    "level_sizes",
    "mip_chain",
    "to_unit",
    "write_dds",
    "write_ktx2",
]

FORMATS = ("bc5", "bc7", "rgba8")

# Vulkan and DXGI format numbers, bytes per 4 x 4 block (or per texel for rgba8).
_VK_FORMAT = {"bc5": 141, "bc7": 145, "rgba8": 37}  # BC5_UNORM_BLOCK, BC7_UNORM_BLOCK, R8G8B8A8_UNORM
_DXGI_FORMAT = {"bc5": 83, "bc7": 98, "rgba8": 28}  # BC5_UNORM, BC7_UNORM, R8G8B8A8_UNORM
_BLOCK_BYTES = {"bc5": 16, "bc7": 16, "rgba8": 4}
_BLOCK_SIDE = {"bc5": 4, "bc7": 4, "rgba8": 1}

KTX2_IDENTIFIER = b"\xabKTX 20\xbb\r\n\x1a\n"


def _check_format(fmt: str) -> str:
    if fmt not in FORMATS:
        raise ValueError(f"unknown GPU format {fmt!r}: expected one of {', '.join(FORMATS)}")
    return fmt


def to_unit(normals: np.ndarray) -> np.ndarray:
    """Unit vectors (H, W, 3) float64 from a map of x, y, z in [-1, 1], or of x, y alone.

    Parameters
    ----------
    normals : ndarray
        (H, W, 3) vectors, or (H, W, 2) x and y with z = sqrt(max(0, 1 - x^2 - y^2)).

    Returns
    -------
    ndarray
        (H, W, 3) unit vectors; a zero vector becomes (0, 0, 1).
    """
    n = np.asarray(normals)
    if n.ndim != 3 or n.shape[2] not in (2, 3) or n.shape[0] < 1 or n.shape[1] < 1:
        raise ValueError(f"a normal map is (H, W, 3) or (H, W, 2) x, y; got shape {n.shape}")
    if not np.issubdtype(n.dtype, np.floating):
        raise ValueError(f"normals must be floats in [-1, 1]; got {n.dtype}")
    n = n.astype(np.float64)
    if not np.isfinite(n).all():
        raise ValueError("normals contain NaN or infinite values")
    if n.shape[2] == 2:
        z = np.sqrt(np.maximum(0.0, 1.0 - n[..., 0] ** 2 - n[..., 1] ** 2))
        n = np.concatenate([n, z[..., None]], axis=2)
    return _renormalise(n)


def _renormalise(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=2, keepdims=True)
    # Opposite vectors can cancel in an average: such a texel has no direction, so it points up.
    flat = length[..., 0] < 1e-12
    out = v / np.where(flat[..., None], 1.0, length)
    out[flat] = (0.0, 0.0, 1.0)
    return out


def level_sizes(width: int, height: int) -> list[tuple[int, int]]:
    """(width, height) of every mip level, the GPU rule: max(1, floor(n / 2^k)) down to 1 x 1."""
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive; got {width} x {height}")
    sizes = [(width, height)]
    while sizes[-1] != (1, 1):
        w, h = sizes[-1]
        sizes.append((max(1, w // 2), max(1, h // 2)))
    return sizes


def _shrink_axis(v: np.ndarray, axis: int, new: int) -> np.ndarray:
    """Area average along one axis from n to ``new`` texels (new = n // 2, or 1).

    Coarse texel i covers [i s, (i + 1) s) of the fine axis, s = n / new, which touches at most
    three fine texels when s < 3 (s = 2 for an even n, 2 + 1/new for an odd one), or all of them
    when new = 1; each counts by the length it shares with the interval.
    """
    n = v.shape[axis]
    if new == n:
        return v
    if new == 1:
        return v.mean(axis=axis, keepdims=True)
    s = n / new
    lo = np.arange(new) * s
    hi = lo + s
    start = np.floor(lo).astype(np.int64)
    out = 0.0
    for k in range(3):
        j = start + k
        weight = np.clip(np.minimum(j + 1, hi) - np.maximum(j, lo), 0.0, None) / s
        taken = np.take(v, np.minimum(j, n - 1), axis=axis)
        shape = [1] * v.ndim
        shape[axis] = new
        out = out + taken * weight.reshape(shape)
    return out


def mip_chain(normals: np.ndarray) -> list[np.ndarray]:
    """Every mip level of a normal map, renormalised to unit vectors, down to 1 x 1.

    Level k is the area average of the base level's unit vectors over its footprint, renormalised:
    the averages are carried unnormalised from level to level (an average of 2 x 2 averages is the
    4 x 4 average) so that the renormalisation of one level does not bias the next, as a mip made
    from the original would not be.

    Parameters
    ----------
    normals : ndarray
        (H, W, 3) float vectors in [-1, 1], or (H, W, 2) x, y (z reconstructed, z >= 0).

    Returns
    -------
    list of ndarray
        Level 0 (the input, renormalised) to the 1 x 1 level, float64, each with the input's
        channels: (h, w, 3) unit vectors, or (h, w, 2) their x and y.

    Examples
    --------
    >>> import numpy as np
    >>> levels = mip_chain(np.dstack([np.zeros((6, 5, 2)), np.ones((6, 5))]))
    >>> [level.shape for level in levels]
    [(6, 5, 3), (3, 2, 3), (1, 1, 3)]
    >>> levels[1][0, 0].tolist()
    [0.0, 0.0, 1.0]
    """
    channels = np.asarray(normals).shape[-1] if np.ndim(normals) == 3 else 3
    unit = to_unit(normals)
    height, width = unit.shape[:2]
    levels = [unit]
    mean = unit
    for w, h in level_sizes(width, height)[1:]:
        mean = _shrink_axis(_shrink_axis(mean, 0, h), 1, w)
        levels.append(_renormalise(mean))
    return [level[..., :channels] for level in levels]


def flip_green(normals: np.ndarray) -> np.ndarray:
    """The other green-channel convention: OpenGL (y up) <-> DirectX (y down).

    Negates y and nothing else. Floats are negated; unsigned integer samples (UNORM) become
    max - v, which is the negation of v / max * 2 - 1. Returns a new array.
    """
    n = np.array(normals, copy=True)
    if n.ndim != 3 or n.shape[2] < 2:
        raise ValueError(f"a normal map is (H, W, C) with C >= 2; got shape {n.shape}")
    if np.issubdtype(n.dtype, np.floating):
        n[..., 1] = -n[..., 1]
    elif np.issubdtype(n.dtype, np.unsignedinteger):
        n[..., 1] = np.iinfo(n.dtype).max - n[..., 1]
    else:
        raise ValueError(f"normals must be floats or unsigned integer samples; got {n.dtype}")
    return n


def _rgba8(unit: np.ndarray) -> np.ndarray:
    """Unit vectors -> (H, W, 4) uint8 UNORM samples, alpha 255."""
    h, w = unit.shape[:2]
    rgba = np.full((h, w, 4), 255, dtype=np.uint8)
    rgba[..., :3] = np.round((unit + 1.0) * 127.5).clip(0, 255).astype(np.uint8)
    return rgba


def _pad_to_blocks(rgba: np.ndarray) -> np.ndarray:
    """Edge-replicated to whole 4 x 4 blocks (the texels past the image are never sampled)."""
    h, w = rgba.shape[:2]
    return np.pad(rgba, ((0, -h % 4), (0, -w % 4), (0, 0)), mode="edge")


def compress(normals: np.ndarray, fmt: str) -> bytes:
    """One level in a GPU format.

    Parameters
    ----------
    normals : ndarray
        (H, W, 3) or (H, W, 2) float normals (see :func:`to_unit`).
    fmt : {"bc5", "bc7", "rgba8"}
        BC5: x, y in the red and green blocks. BC7 and RGBA8: x, y, z in red, green, blue
        (alpha 255). Block formats pad to whole 4 x 4 blocks, as the containers store them.

    Returns
    -------
    bytes
        The blocks in row-major order (or the RGBA8 texels).
    """
    _check_format(fmt)
    rgba = _rgba8(to_unit(normals))
    if fmt == "rgba8":
        return rgba.tobytes()
    padded = np.ascontiguousarray(_pad_to_blocks(rgba))
    h, w = padded.shape[:2]
    if fmt == "bc5":
        import quicktex
        from quicktex.s3tc.bc5 import BC5Encoder

        texture = quicktex.RawTexture.frombytes(padded.tobytes(), w, h)
        return bytes(BC5Encoder(0, 1).encode(texture).tobytes())
    import etcpak

    return bytes(etcpak.compress_bc7(padded.tobytes(), w, h, None))


def _level_bytes(fmt: str, width: int, height: int) -> int:
    side = _BLOCK_SIDE[fmt]
    return -(-width // side) * -(-height // side) * _BLOCK_BYTES[fmt]


def decode_blocks(data: bytes, width: int, height: int, fmt: str) -> np.ndarray:
    """One level's blocks back to samples, by texture2ddecoder (RGBA8 needs no decoder).

    Returns
    -------
    ndarray
        uint8, (height, width, 2) x, y samples for BC5, (height, width, 4) RGBA otherwise.
    """
    _check_format(fmt)
    expected = _level_bytes(fmt, width, height)
    if len(data) != expected:
        raise ValueError(f"{fmt} level of {width} x {height} needs {expected} bytes; got {len(data)}")
    if fmt == "rgba8":
        return np.frombuffer(data, dtype=np.uint8).reshape(height, width, 4).copy()
    import texture2ddecoder

    pw, ph = -(-width // 4) * 4, -(-height // 4) * 4
    decode = texture2ddecoder.decode_bc5 if fmt == "bc5" else texture2ddecoder.decode_bc7
    bgra = np.frombuffer(decode(bytes(data), pw, ph), dtype=np.uint8).reshape(ph, pw, 4)
    rgba = bgra[:height, :width, [2, 1, 0, 3]]
    return np.ascontiguousarray(rgba[..., :2] if fmt == "bc5" else rgba)


def _decoded_unit(decoded: np.ndarray) -> np.ndarray:
    d = np.asarray(decoded)
    if d.ndim != 3 or d.shape[2] not in (2, 3, 4):
        raise ValueError(f"decoded blocks are (H, W, 2) x, y or (H, W, 3|4) RGB(A); got {d.shape}")
    if np.issubdtype(d.dtype, np.unsignedinteger):
        v = d.astype(np.float64) / np.iinfo(d.dtype).max * 2.0 - 1.0
    elif np.issubdtype(d.dtype, np.floating):
        v = d.astype(np.float64)
    else:
        raise ValueError(f"decoded blocks must be UNORM samples or floats; got {d.dtype}")
    # The shader's reconstruction: z from x and y for two channels, a renormalisation for three.
    return to_unit(v[..., :2] if v.shape[2] == 2 else v[..., :3])


@dataclass(frozen=True)
class AngularError:
    """Angles in degrees between two normal maps: their mean and 99th percentile."""

    mean: float
    p99: float


def angular_error_added(normals: np.ndarray, blocks_decoded: np.ndarray) -> AngularError:
    """The angle a GPU format adds to a normal map, in degrees.

    Parameters
    ----------
    normals : ndarray
        The map the blocks were made from, (H, W, 3) or (H, W, 2) floats (see :func:`to_unit`).
    blocks_decoded : ndarray
        The blocks decoded: (H, W, 2) x, y (BC5; z = sqrt(1 - x^2 - y^2) as a shader does) or
        (H, W, 3|4) RGB(A) (BC7, RGBA8; renormalised), as UNORM integers (v / max * 2 - 1) or
        floats in [-1, 1].

    Returns
    -------
    AngularError
        Mean and 99th percentile over the texels. The 8-bit rounding is part of what is added.
    """
    a = to_unit(normals)
    b = _decoded_unit(blocks_decoded)
    if a.shape != b.shape:
        raise ValueError(f"normals are {a.shape[:2]} but the decoded blocks {b.shape[:2]}")
    cosine = np.clip((a * b).sum(axis=2), -1.0, 1.0)
    angles = np.degrees(np.arccos(cosine))
    return AngularError(float(angles.mean()), float(np.percentile(angles, 99)))


def _check_levels(levels: Sequence[bytes], width: int, height: int, fmt: str) -> list[tuple[int, int]]:
    _check_format(fmt)
    sizes = level_sizes(width, height)
    if not 1 <= len(levels) <= len(sizes):
        raise ValueError(f"a {width} x {height} texture has 1 to {len(sizes)} levels; got {len(levels)}")
    for k, (data, (w, h)) in enumerate(zip(levels, sizes, strict=False)):
        if len(data) != _level_bytes(fmt, w, h):
            raise ValueError(
                f"level {k} ({w} x {h}) of {fmt} needs {_level_bytes(fmt, w, h)} bytes; got {len(data)}"
            )
    return sizes[: len(levels)]


def _dfd(fmt: str) -> bytes:
    """The data format descriptor: its total size, then one Khronos basic descriptor block."""
    # (bit offset, bit length, channel id, lower, upper) per sample; lengths are stored minus one.
    if fmt == "rgba8":
        model, block, plane = 1, (0, 0, 0, 0), 4  # KHR_DF_MODEL_RGBSDA, one texel, 4 bytes
        samples = [(8 * c, 8, ch, 0, 255) for c, ch in enumerate((0, 1, 2, 15))]  # R, G, B, alpha=15
    elif fmt == "bc5":
        model, block, plane = 132, (3, 3, 0, 0), 16  # KHR_DF_MODEL_BC5, 4 x 4 texels
        samples = [(0, 64, 0, 0, 0xFFFFFFFF), (64, 64, 1, 0, 0xFFFFFFFF)]  # BC5 red, BC5 green
    else:
        model, block, plane = 134, (3, 3, 0, 0), 16  # KHR_DF_MODEL_BC7
        samples = [(0, 128, 0, 0, 0xFFFFFFFF)]
    block_size = 24 + 16 * len(samples)
    words = struct.pack(
        "<IHHBBBB4B8B",
        0,  # vendor id 0 (Khronos), descriptor type 0 (basic format)
        2,  # version number: KHR_DF_VERSIONNUMBER_1_3
        block_size,
        model,
        1,  # colour primaries: BT.709
        1,  # transfer function: linear (UNORM data, no sRGB curve)
        0,  # flags: straight alpha
        *block,
        plane,
        *([0] * 7),
    )
    for offset, length, channel, lower, upper in samples:
        words += struct.pack("<HBB4BII", offset, length - 1, channel, 0, 0, 0, 0, lower, upper)
    return struct.pack("<I", 4 + len(words)) + words


def _kvd(writer: str) -> bytes:
    """The key/value data: one KTXwriter entry, padded to 4 bytes."""
    entry = b"KTXwriter\x00" + writer.encode() + b"\x00"
    data = struct.pack("<I", len(entry)) + entry
    return data + b"\x00" * (-len(data) % 4)


def _write_out(path_or_file: str | Path | BinaryIO, data: bytes) -> None:
    if hasattr(path_or_file, "write"):
        path_or_file.write(data)  # type: ignore[union-attr]
    else:
        Path(path_or_file).write_bytes(data)


def write_ktx2(
    path_or_file: str | Path | BinaryIO,
    levels: Sequence[bytes],
    width: int,
    height: int,
    fmt: str,
    *,
    writer: str = "bandelets",
) -> int:
    """A KTX 2.0 file: one 2D texture, its mip levels, no supercompression.

    Parameters
    ----------
    path_or_file : str, Path or binary file
        Where to write.
    levels : sequence of bytes
        Level 0 (width x height) first, each as :func:`compress` gives it; any number of levels
        from 1 to the full chain.
    width, height : int
        Level 0's size.
    fmt : {"bc5", "bc7", "rgba8"}
        VK_FORMAT_BC5_UNORM_BLOCK, VK_FORMAT_BC7_UNORM_BLOCK or VK_FORMAT_R8G8B8A8_UNORM.
    writer : str
        The KTXwriter value.

    Returns
    -------
    int
        The file's size in bytes.
    """
    _check_levels(levels, width, height, fmt)
    count = len(levels)
    # Layout: identifier, header (9 x u32), index (4 x u32 + 2 x u64), level index (3 x u64 per
    # level), DFD, key/value data, then the levels, smallest first, each aligned to
    # lcm(texel block size, 4) bytes (16 for BC5 / BC7, 4 for RGBA8).
    dfd = _dfd(fmt)
    kvd = _kvd(writer)
    dfd_offset = 12 + 36 + 32 + 24 * count
    kvd_offset = dfd_offset + len(dfd)
    position = kvd_offset + len(kvd)
    alignment = 16 if fmt != "rgba8" else 4
    offsets = [0] * count
    body = b""
    for k in reversed(range(count)):
        padding = -position % alignment
        body += b"\x00" * padding
        position += padding
        offsets[k] = position
        body += bytes(levels[k])
        position += len(levels[k])
    # typeSize 1, pixelDepth 0 (2D), layerCount 0 (not an array), 1 face, no supercompression.
    header = KTX2_IDENTIFIER + struct.pack("<9I", _VK_FORMAT[fmt], 1, width, height, 0, 0, 1, count, 0)
    index = struct.pack("<4I2Q", dfd_offset, len(dfd), kvd_offset, len(kvd), 0, 0)
    level_index = b"".join(
        struct.pack("<3Q", offsets[k], len(levels[k]), len(levels[k])) for k in range(count)
    )
    data = header + index + level_index + dfd + kvd + body
    _write_out(path_or_file, data)
    return len(data)


def write_dds(
    path_or_file: str | Path | BinaryIO, levels: Sequence[bytes], width: int, height: int, fmt: str
) -> int:
    """A DDS file with the DX10 header extension: one 2D texture and its mip levels.

    Parameters are as for :func:`write_ktx2` (DXGI_FORMAT_BC5_UNORM, BC7_UNORM or
    R8G8B8A8_UNORM). Returns the file's size in bytes.
    """
    _check_levels(levels, width, height, fmt)
    count = len(levels)
    compressed = fmt != "rgba8"
    # DDSD_CAPS | HEIGHT | WIDTH | PIXELFORMAT, MIPMAPCOUNT, and LINEARSIZE (blocks) or PITCH (rows).
    flags = 0x1 | 0x2 | 0x4 | 0x1000 | 0x20000 | (0x80000 if compressed else 0x8)
    pitch = len(levels[0]) if compressed else 4 * width
    caps = 0x1000 | ((0x8 | 0x400000) if count > 1 else 0)  # TEXTURE, and COMPLEX | MIPMAP
    pixel_format = struct.pack("<II4s5I", 32, 0x4, b"DX10", 0, 0, 0, 0, 0)  # DDPF_FOURCC
    header = struct.pack("<7I", 124, flags, height, width, pitch, 0, count) + b"\x00" * 44
    header += pixel_format + struct.pack("<5I", caps, 0, 0, 0, 0)
    # DDS_HEADER_DXT10: format, TEXTURE2D (3), no misc flags, array size 1, alpha mode unknown.
    dx10 = struct.pack("<5I", _DXGI_FORMAT[fmt], 3, 0, 1, 0)
    data = b"DDS " + header + dx10 + b"".join(bytes(level) for level in levels)
    _write_out(path_or_file, data)
    return len(data)


@dataclass(frozen=True)
class Export:
    """What :func:`export` wrote: the format, container, level sizes, file size and added error."""

    fmt: str
    container: str
    sizes: list[tuple[int, int]]
    file_bytes: int
    error: AngularError
    level_errors: list[AngularError] = field(default_factory=list)


def export(
    path_or_file: str | Path | BinaryIO,
    normals: np.ndarray,
    fmt: str | None = None,
    *,
    mips: bool = True,
    container: str | None = None,
) -> Export:
    """A normal map to a KTX2 or DDS file, with its renormalised mip chain, and the error added.

    Parameters
    ----------
    path_or_file : str, Path or binary file
        The output; its suffix (.ktx2 or .dds) names the container unless ``container`` does.
    normals : ndarray
        (H, W, 3) or (H, W, 2) float normals (the decoded map).
    fmt : {"bc5", "bc7", "rgba8"}, optional
        Default: BC5 for an x, y map, BC7 for three channels.
    mips : bool
        The whole chain down to 1 x 1, or level 0 alone.
    container : {"ktx2", "dds"}, optional

    Returns
    -------
    Export
        ``error`` is level 0's angle added by the format (the figure for the summary line),
        ``level_errors`` every level's against its renormalised mip.
    """
    shape = np.shape(normals)
    fmt = _check_format(fmt or ("bc5" if len(shape) == 3 and shape[2] == 2 else "bc7"))
    if container is None:
        suffix = Path(getattr(path_or_file, "name", path_or_file)).suffix.lower().lstrip(".")
        container = suffix
    if container not in ("ktx2", "dds"):
        raise ValueError(f"GPU output is a .ktx2 or .dds file; got {container!r}")
    chain = mip_chain(normals) if mips else [to_unit(normals)]
    blocks = [compress(level, fmt) for level in chain]
    errors = []
    for level, data in zip(chain, blocks, strict=True):
        h, w = level.shape[:2]
        errors.append(angular_error_added(level, decode_blocks(data, w, h, fmt)))
    height, width = chain[0].shape[:2]
    write = write_ktx2 if container == "ktx2" else write_dds
    size = write(path_or_file, blocks, width, height, fmt)
    sizes = [(level.shape[1], level.shape[0]) for level in chain]
    return Export(fmt, container, sizes, size, errors[0], errors)
