"""The .bdl file format.

Layout (little endian)::

    offset  size  field
    0       4     magic b"BDL\\x1a"
    4       1     format version (FORMAT_VERSION)
    5       1     kind: 0 image, 1 normal-map, 2 geometry-image
    6       1     transform: 0 bandelet, 1 wavelet
    7       1     wavelet: index into bandelets.wavelets.WAVELETS
    8       1     wavelet levels
    9       1     channels coded (1 to 4; a normal map: 3, or 2 when z is rebuilt, see below)
    10      1     source sample depth: 0 float, 8 or 16 (PNG bits, for decoding back to PNG)
    11      1     1D transform along the directions: 0 haar, 1 alpert2
    12      4     height
    16      4     width
    20      8     threshold T (float64)
    28      4x3   byte lengths of the streams: quadtree splits, directions, coefficients
    40      1     restoration iterations, 0 to 100 (0: off; :mod:`bandelets.restoration`)
    41      ...   geometry-image options (kind 2 only, 10 bytes, see below)
    41/51   ...   the three streams
    end-4   4     CRC32 of everything before it

A normal map whose every vector has ``z >= 0`` (tangent-space and height-field maps) is
coded as its two channels ``x, y``; the decoder rebuilds ``z = sqrt(1 - x^2 - y^2)``
(format version 2; version 1 always coded three channels). Format version 3 added the
restoration byte; version 4 changed the restoration's penalty (a log total variation instead of
the total variation) and restores a normal map coded with its three channels on the unit sphere
(:mod:`bandelets.restoration`); version 5 added a second-order term to that penalty, codes a
normal map of three channels in local frames around its coarser normals (implied by the kind and
the channel count, weight :data:`bandelets.frames.NORMAL_MAP_WEIGHT`: no header field) and lets
files with local frames be restored. Version 6 fixed the basis of Alpert's multiwavelet by
construction (:func:`bandelets.bandeletize.alpert_matrices`: version 5 took it from an SVD whose
rotation depended on the CPU's LAPACK kernels). This build reads version 6 only.

Geometry-image options (format version 2), right after the fixed header of a file of kind 2::

    0       1     wavelet boundary extension: index into bandelets.wavelets.EXTENSIONS
                  (0 symmetric, 1 spherical: cdf97, square, side a multiple of 2**levels)
    1       1     local frames: 0 off, 1 on (:mod:`bandelets.frames`)
    2       8     weight of the normal component (float64; 1 when the frames are off)

Every field is validated before anything is allocated; :class:`FormatError` (a ``ValueError``)
names what is wrong. Beyond the size limits, :func:`check_memory` refuses a file whose decoding
would need more than ``max_memory`` bytes: a few bytes of range-coded zeros can legitimately
describe a huge image, so the size of the file says nothing about the work it asks for.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, replace

import numpy as np

from .bandeletize import TRANSFORMS_1D
from .frames import NORMAL_MAP_WEIGHT
from .restoration import MAX_ITERATIONS
from .wavelets import EXTENSIONS, MAX_LEVELS, WAVELETS, padded_shape

__all__ = [
    "FORMAT_VERSION",
    "KINDS",
    "TRANSFORMS",
    "MAX_SIDE",
    "MAX_SAMPLES",
    "MAX_MEMORY",
    "check_memory",
    "decoder_memory",
    "encoder_memory",
    "FormatError",
    "HEADER_BYTES",
    "Header",
    "pack",
    "unpack",
]

MAGIC = b"BDL\x1a"
FORMAT_VERSION = 6
KINDS = ("image", "normal-map", "geometry-image")
TRANSFORMS = ("bandelet", "wavelet")
#: Largest side and sample count a decoder accepts by default.
MAX_SIDE = 16384
MAX_SAMPLES = 2**28
#: Largest working set, in bytes, the decoder (and the encoder) accepts by default.
MAX_MEMORY = 2 * 2**30

# Working set per padded pixel and per padded sample, measured with tracemalloc (peak of the
# numpy allocations, JIT compiled beforehand) on generated normal maps and their first channel:
# decode 512 x 512 x 1 and 1024 x 1024 x 1 and 2048 x 2048 x 1 peak at 72 B/sample,
# 512 x 512 x 3 and 1024 x 1024 x 3 at 42 B/sample, i.e. about 45 B/pixel + 27 B/sample;
# the estimate rounds up. Encoding at a fixed threshold peaks at 164 MiB for 512 x 512 x 1,
# 387 MiB for 2048 x 2048 x 1 (about 150 MiB of tables, the reorderings of every direction up
# to 32 x 32, plus 59 B/sample), 213 MiB for 1024 x 1024 x 3; a bpp target (rate control)
# peaks no higher than a fixed threshold (512 x 512 x 3, 170 MiB). The estimate rounds up.
# The decoder transforms the channels in parallel threads, so its peak varies with how they
# interleave: up to 162 B/pixel for 128 x 192 x 3 and 153 for 512 x 512 x 3 (15 decodes each),
# hence 48 B/sample rather than 32.
_DECODE_PER_PIXEL, _DECODE_PER_SAMPLE = 48, 48
# Local frames add the surface of the coarser levels and its frames: 256 x 256
# and 512 x 512 peak at 153 B/pixel against 119 B/pixel without.
_DECODE_FRAMES_PER_PIXEL = 48
# The restoration (bin bounds, the penalty's gradient) peaks at 85 B/pixel for 512 x 512 x 1
# and 1024 x 1024 x 1, 237 B/pixel for 512 x 512 x 3, against 54 and 90 without.
_DECODE_RESTORATION_PER_SAMPLE = 56
_ENCODE_FIXED, _ENCODE_PER_SAMPLE = 160 * 2**20, 96

_FIXED = struct.Struct("<4sBBBBBBBBIId3IB")
#: Size of the smallest possible file: the fixed header and the CRC.
HEADER_BYTES = _FIXED.size + 4
#: Options of a geometry image: extension, frames, normal weight.
_GEOMETRY = struct.Struct("<BBd")
#: Range of the normal weight a file may hold.
MIN_NORMAL_WEIGHT, MAX_NORMAL_WEIGHT = 1 / 64, 64.0
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
    # Geometry images (the defaults for any other kind, except frames with NORMAL_MAP_WEIGHT for a
    # normal map of three channels):
    extension: str = "symmetric"
    frames: bool = False
    normal_weight: float = 1.0
    #: Iterations of :func:`bandelets.restoration.iterate` the decoder runs (0: none).
    restoration: int = 0


def implied_options(kind: str, channels: int) -> dict:
    """The fields of :class:`Header` that the file does not store for ``kind`` (any kind but a
    geometry image) and ``channels``: local frames for a normal map of three channels."""
    if kind == "normal-map" and channels == 3:
        return {"frames": True, "normal_weight": NORMAL_MAP_WEIGHT}
    return {}


def decoder_memory(
    height: int, width: int, channels: int, levels: int, frames: bool = False, restoration: bool = False
) -> int:
    """Estimated peak bytes the decoder allocates for an image of this size (``frames``: local
    frames; ``restoration``: restoration iterations)."""
    rows, cols = padded_shape((height, width), levels)
    extra = _DECODE_FRAMES_PER_PIXEL if frames else 0
    per_sample = _DECODE_PER_SAMPLE + (_DECODE_RESTORATION_PER_SAMPLE if restoration else 0)
    return rows * cols * (_DECODE_PER_PIXEL + extra + per_sample * channels)


def encoder_memory(height: int, width: int, channels: int) -> int:
    """Estimated peak bytes the encoder allocates for an image of this size."""
    rows, cols = padded_shape((height, width), MAX_LEVELS)
    return _ENCODE_FIXED + rows * cols * channels * _ENCODE_PER_SAMPLE


def check_memory(header: Header, max_memory: int = MAX_MEMORY) -> None:
    """Raise :class:`FormatError` if decoding ``header`` needs more than ``max_memory`` bytes.

    Also refuses more wavelet levels than the image has octaves: that is pure padding (the
    encoder never writes it), and the first use of a deep level costs seconds (the synthesis
    norms of :mod:`bandelets.wavelets`).
    """
    if header.levels > 1 and 2**header.levels > min(header.height, header.width):
        raise FormatError(
            f"corrupt .bdl file: {header.levels} wavelet levels for a {header.width} x {header.height} image"
        )
    need = decoder_memory(
        header.height, header.width, header.channels, header.levels, header.frames, header.restoration > 0
    )
    if need > max_memory:
        raise FormatError(
            f"decoding this {header.width} x {header.height} x {header.channels} image needs about "
            f"{need / 2**20:.0f} MiB, above the limit of {max_memory / 2**20:.0f} MiB (max_memory)"
        )


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
        header.restoration,
    )
    if header.kind != "geometry-image":  # its options are not stored, so they must be the implied ones
        defaults = {
            "extension": Header.extension,
            "frames": Header.frames,
            "normal_weight": Header.normal_weight,
        }
        if header != replace(header, **(defaults | implied_options(header.kind, header.channels))):
            raise ValueError(
                f"a {header.kind} of {header.channels} channels has no choice of extension, frames or "
                f"normal weight: {header}"
            )
    if header.kind == "geometry-image":
        body += _GEOMETRY.pack(EXTENSIONS.index(header.extension), int(header.frames), header.normal_weight)
    body += b"".join(streams)
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
    lengths, restoration = fields[12:15], fields[15]
    start = _FIXED.size + (_GEOMETRY.size if kind == KINDS.index("geometry-image") else 0)
    checks = [
        (kind < len(KINDS), f"unknown kind code {kind}"),
        (
            kind == 0 or channels == 3 or (kind == 1 and channels == 2),
            f"a {KINDS[min(kind, 2)]} needs 3 channels{' (or 2)' if kind == 1 else ''}, "
            f"the file has {channels}",
        ),
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
        (sum(lengths) == len(body) - start, "stream lengths do not match the file size"),
        (restoration <= MAX_ITERATIONS, f"{restoration} restoration iterations (at most {MAX_ITERATIONS})"),
    ]
    for ok, message in checks:
        if not ok:
            raise FormatError(f"corrupt .bdl file: {message}")
    if not 1 <= levels <= MAX_LEVELS:
        raise FormatError(f"corrupt .bdl file: bad number of wavelet levels {levels}")
    options = {}
    if KINDS[kind] == "geometry-image":
        options = _geometry_options(data, WAVELETS[wavelet], levels, height, width)
    else:
        options = implied_options(KINDS[kind], channels)
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
        **options,
        restoration=restoration,
    )
    streams = []
    for n in lengths:
        streams.append(bytes(data[start : start + n]))
        start += n
    return header, tuple(streams)


def _geometry_options(data: bytes, wavelet: str, levels: int, height: int, width: int) -> dict:
    """Validated geometry-image options of a file (its fixed header already validated)."""
    extension, frames, weight = _GEOMETRY.unpack_from(data, _FIXED.size)
    checks = [
        (extension < len(EXTENSIONS), f"unknown extension code {extension}"),
        (frames in (0, 1), f"bad local frames flag {frames}"),
        (
            bool(frames) or weight == 1.0,
            f"normal weight {weight} without local frames",
        ),
        (
            np.isfinite(weight) and MIN_NORMAL_WEIGHT <= weight <= MAX_NORMAL_WEIGHT,
            f"bad normal weight {weight}",
        ),
        (
            extension != EXTENSIONS.index("spherical")
            or (wavelet == "cdf97" and height == width and height % (1 << levels) == 0),
            f"spherical extension of a {width} x {height} {wavelet} image at {levels} levels",
        ),
    ]
    for ok, message in checks:
        if not ok:
            raise FormatError(f"corrupt .bdl file: {message}")
    return {"extension": EXTENSIONS[extension], "frames": bool(frames), "normal_weight": weight}
