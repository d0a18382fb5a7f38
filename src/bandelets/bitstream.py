"""The .bdl file format.

Layout (little endian)::

    offset  size  field
    0       4     magic b"BDL\\x1a"
    4       1     format version (FORMAT_VERSION)
    5       1     kind: 0 image, 1 normal-map, 2 geometry-image
    6       1     transform: 0 bandelet, 1 wavelet
    7       1     wavelet: index into bandelets.wavelets.WAVELETS
    8       1     wavelet levels
    9       1     channels (1 to 4)
    10      1     source sample depth: 0 float, 8 or 16 (PNG bits, for decoding back to PNG)
    11      1     1D transform along the directions: 0 haar, 1 alpert2
    12      4     height
    16      4     width
    20      8     threshold T (float64)
    28      4x3   byte lengths of the streams: quadtree splits, directions, coefficients
    40      ...   the three streams
    end-4   4     CRC32 of everything before it

Every field is validated before anything is allocated; :class:`FormatError` (a ``ValueError``)
names what is wrong.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

import numpy as np

from .bandeletize import TRANSFORMS_1D
from .wavelets import MAX_LEVELS, WAVELETS

__all__ = [
    "FORMAT_VERSION",
    "KINDS",
    "TRANSFORMS",
    "MAX_SIDE",
    "MAX_SAMPLES",
    "FormatError",
    "HEADER_BYTES",
    "Header",
    "pack",
    "unpack",
]

MAGIC = b"BDL\x1a"
FORMAT_VERSION = 1
KINDS = ("image", "normal-map", "geometry-image")
TRANSFORMS = ("bandelet", "wavelet")
#: Largest side and sample count a decoder accepts by default.
MAX_SIDE = 16384
MAX_SAMPLES = 2**28

_FIXED = struct.Struct("<4sBBBBBBBBIId3I")
#: Size of the smallest possible file: the fixed header and the CRC.
HEADER_BYTES = _FIXED.size + 4
_STREAMS = ("splits", "directions", "coefficients")


class FormatError(ValueError):
    """A .bdl file is corrupt, truncated, hostile or of an unsupported version."""


@dataclass(frozen=True)
class Header:
    """Everything a .bdl file says before its streams."""

    height: int
    width: int
    channels: int
    kind: str
    transform: str
    wavelet: str
    levels: int
    threshold: float
    depth: int = 0
    transform_1d: str = "alpert2"


def pack(header: Header, streams: tuple[bytes, bytes, bytes]) -> bytes:
    """Assemble a .bdl file from its header and its three coded streams."""
    body = _FIXED.pack(
        MAGIC,
        FORMAT_VERSION,
        KINDS.index(header.kind),
        TRANSFORMS.index(header.transform),
        WAVELETS.index(header.wavelet),
        header.levels,
        header.channels,
        header.depth,
        TRANSFORMS_1D.index(header.transform_1d),
        header.height,
        header.width,
        header.threshold,
        *(len(s) for s in streams),
    ) + b"".join(streams)
    return body + struct.pack("<I", zlib.crc32(body))


def unpack(
    data: bytes, *, max_side: int = MAX_SIDE, max_samples: int = MAX_SAMPLES
) -> tuple[Header, tuple[bytes, bytes, bytes]]:
    """Parse and validate a .bdl file.

    Parameters
    ----------
    data : bytes
        The whole file.
    max_side, max_samples : int
        Limits on the image size (per side, and height x width x channels).

    Returns
    -------
    header : Header
    streams : (splits, directions, coefficients) bytes

    Raises
    ------
    FormatError
    """
    if len(data) < 4 or data[:4] != MAGIC:
        raise FormatError("not a .bdl file (bad magic number)")
    if len(data) < _FIXED.size + 4:
        raise FormatError(f"truncated .bdl file ({len(data)} bytes)")
    fields = _FIXED.unpack_from(data)
    version = fields[1]
    if version != FORMAT_VERSION:
        raise FormatError(
            f".bdl format version {version} is not supported (this build reads version {FORMAT_VERSION})"
        )
    body, crc = data[:-4], struct.unpack("<I", data[-4:])[0]
    if zlib.crc32(body) != crc:
        raise FormatError("corrupt .bdl file (CRC32 mismatch)")
    kind, transform, wavelet, levels, channels, depth, along, height, width, threshold = fields[2:12]
    lengths = fields[12:]
    checks = [
        (kind < len(KINDS), f"unknown kind code {kind}"),
        (kind == 0 or channels == 3, f"a {KINDS[min(kind, 2)]} needs 3 channels, the file has {channels}"),
        (transform < len(TRANSFORMS), f"unknown transform code {transform}"),
        (wavelet < len(WAVELETS), f"unknown wavelet code {wavelet}"),
        (1 <= channels <= 4, f"bad channel count {channels}"),
        (depth in (0, 8, 16), f"bad sample depth {depth}"),
        (along < len(TRANSFORMS_1D), f"unknown 1D transform code {along}"),
        (
            1 <= height <= max_side and 1 <= width <= max_side,
            f"image size {width} x {height} exceeds the limit of {max_side} per side",
        ),
        (
            height * width * channels <= max_samples,
            f"image of {height * width * channels} samples exceeds the limit of {max_samples}",
        ),
        (np.isfinite(threshold) and threshold > 0, f"bad threshold {threshold}"),
        (sum(lengths) == len(body) - _FIXED.size, "stream lengths do not match the file size"),
    ]
    for ok, message in checks:
        if not ok:
            raise FormatError(f"corrupt .bdl file: {message}")
    if not 1 <= levels <= MAX_LEVELS:
        raise FormatError(f"corrupt .bdl file: bad number of wavelet levels {levels}")
    header = Header(
        height,
        width,
        channels,
        KINDS[kind],
        TRANSFORMS[transform],
        WAVELETS[wavelet],
        levels,
        threshold,
        depth,
        TRANSFORMS_1D[along],
    )
    streams, start = [], _FIXED.size
    for n in lengths:
        streams.append(bytes(data[start : start + n]))
        start += n
    return header, tuple(streams)
