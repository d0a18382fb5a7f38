"""The .bdl file format.

Layout (little endian)::

    offset  size  field
    0       4     magic b"BDL\\x1a"
    4       1     format version (FORMAT_VERSION)
    5       1     kind: KIND_CODES (0 image, 1 normal-map, 2 geometry-image)
    6       1     transform: TRANSFORM_CODES (0 bandelet, 1 wavelet, 2 lossless), plus 4 times the
                  wavelet: WAVELET_CODES, plus 32 times the 1D transform along the directions:
                  TRANSFORM_1D_CODES (0 haar, 1 alpert2), plus 64 times the LAYOUT_CODES of a
                  normal map's source
    7       1     wavelet levels (1 to MAX_LEVELS), plus 8 times the channels coded less one (1 to
                  4; a normal map: 3, or 2 when z is rebuilt, see below), plus 32 times the source's
                  sample depth: DEPTH_CODES (0 float, 1 8-bit, 2 16-bit: bits of PNG or TIFF
                  samples, for decoding back to them); the top bit is 0
    8       1     restoration iterations, 0 to 100 (0: off; :mod:`bandelets.restore.restoration`), plus 128
                  if the file has a loop filter (format version 11)
    9       1     finest wavelet levels lifted along directions (0: none;
                  :mod:`bandelets.transform.directional`), plus 32 if the two channels of a normal map
                  are coded as their Riesz pair,
                  64 more if its rows run against the slope (format version 15, see below),
                  plus 128 if the image is folded (format version 14, see below)
    10      4     threshold T (float32, MIN_THRESHOLD to MAX_THRESHOLD)
    14      ...   height, width, then the byte lengths of the three streams (quadtree splits,
                  directions, coefficients): five unsigned LEB128 integers (7 bits a byte, low
                  bits first, the top bit set on every byte but the last; at most 5 bytes, no
                  needless trailing byte, below 2**32)
    ...     ...   geometry-image options (kind 2 only, see below)
    ...     ...   the three streams
    ...     ...   the loop filter (format version 11; when byte 8 says so)
    end-4   4     CRC32 of everything before it

Until version 10, a normal map whose every vector has ``z >= 0`` (tangent-space and height-field
maps) was coded as its two channels ``x, y``; the decoder rebuilds ``z = sqrt(1 - x^2 - y^2)``
(format version 2; version 1 always coded three channels). Format version 3 added the restoration
byte; version 4 changed the restoration's penalty (a log total variation instead of the total
variation) and restores a normal map coded with its three channels on the unit sphere
(:mod:`bandelets.restore.restoration`); version 5 added a second-order term to that penalty, codes a normal
map of three channels in local frames around its coarser normals (implied by the kind and the
channel count, weight :data:`NORMAL_MAP_WEIGHT`: no header field) and lets files with local frames
be restored. Version 6 fixed the basis of Alpert's multiwavelet by construction
(:func:`bandelets.transform.bandeletize.alpert_matrices`: version 5 took it from an SVD whose rotation
depended on the CPU's LAPACK kernels). Version 7 added direction-adaptive lifting at the finest
levels (cdf97 without local frames, :mod:`bandelets.transform.directional`; its directions end the directions
stream). Version 8 added the vertex count of the source mesh to the geometry-image options. Version
9 projects the restoration into the bins every :data:`bandelets.restore.restoration.PROJECT_EVERY`
iterations, not at every one, changed the coefficient stream's contexts (:mod:`bandelets.coding.rangecoder`:
backed by coarse contexts, the sign's upper neighbour, the sibling subband, one class per level),
and added tiled files (a container of files of one tile, :mod:`bandelets.codec.tiles`). Version 10 gave
the 1D bandelet coefficients contexts of their own (:mod:`bandelets.coding.squarecontexts`: what the
sibling and parent subbands hold around the square, and the signs of the two channels' coefficients
square by square), let a normal map coded with its three channels (in local frames) be lifted along
directions, computes the restoration's gradient in float32 (the steps' images too, where the
samples' scale allows: :data:`bandelets.restore.restoration.SINGLE_UP_TO`), and has its encoder write the
fewest restoration iterations that keep 97 % of the best gain
(:data:`bandelets.codec.encoder.RESTORATION_SHARE`). Version 11 codes the two channels of a normal map of
layout ``xyz`` as the azimuthal equidistant coordinates of its vectors
(:func:`bandelets.codec.normalmaps.equidistant`), not ``x, y``, and codes so every map whose vectors lie
within :data:`bandelets.codec.normalmaps.ONE_WAY` of +z. Version 11 also added the loop filter
(:mod:`bandelets.restore.loopfilter`), after the streams, reconstructs a bin at its middle
(:data:`bandelets.format.quantizer.RECONSTRUCTION`, 0.44 of the bin before) and codes the lifting blocks'
moved flags in the context of their neighbours (:func:`bandelets.coding.rangecoder.code_flag_map`). Version
12 lets the loop filter take its taps on the other channels over the 5 x 5 square, not only the 3 x
3, and its own taps over a square, not only a diamond, and added lossless files (transform code 2,
:mod:`bandelets.coding.lossless`): the integer samples of every channel of the source (depth 8 or 16),
predicted and coded in the coefficient stream; the splits and directions streams are empty, the
file has no restoration, lifting or loop filter, its threshold is 1 and its wavelet levels 1 (no
meaning), a normal map's channels are the stored ones (3, or 2 of layout ``xy``) and decode to the
source's values, not renormalised. Version 12 also adds two lifting codes, 13 and 14, that lift
each pair of samples of a block on its own (:data:`bandelets.transform.directional.PAIR_BEFORE`,
:data:`bandelets.transform.directional.PAIR_AFTER`) and quantizes the finest wavelet level with a finer step,
``T / FINEST_WEIGHT`` (:data:`bandelets.transform.wavelets.FINEST_WEIGHT`). Version 13 turns the first
tangent of a normal map's local frames towards the direction along which its coarse normals turn
most (:func:`bandelets.transform.frames.normal_map_frames`), not the x axis projected. Version 14 added the
folded flag of a normal map (byte 41 until version 16, byte 9 since): the normals of a closed
surface sampled on an octahedral geometry image (:func:`bandelets.codec.normalmaps.octahedral`), glued
across each edge to itself reversed, as a geometry image of spherical extension is; the restoration
then takes the differences across those folds (:mod:`bandelets.restore.restoration`). Only a lossy normal
map of three channels, square, its side a multiple of ``2**levels``, may be folded. Version 15 may
code the two channels of a lossy normal map as their Riesz pair (the same byte,
:attr:`Header.riesz`, :mod:`bandelets.transform.riesz`): the channel along the gradients of a height and the
one across them; the decoder turns them back at the end of every synthesis. Version 16 codes the
significance and the first two magnitude decisions of the detail coefficients from their contexts
mixed with an activity context, and their larger magnitudes in contexts of that activity
(:func:`bandelets.coding.coefficients.code_coefficients`); the header is unchanged. Version 17 packs the
header: the codes of the transform, wavelet, 1D transform and layout share one byte, the levels,
channels and depth another, the threshold is a float32 (a float64 before) and the sides and the
stream lengths LEB128 integers (uint32s before), as are the geometry-image options (the frames flag
beside the extension, the normal weight a float32, the mesh vertices an LEB128 integer): the 46
bytes of header and CRC of a 256 x 256 normal map became 27 (1 % of a file at 0.25 bpp, where every
byte is worth a coefficient). Version 17 also codes the lifting directions of every pass with one
adaptive model, not one per pass (:func:`bandelets.transform.directional.code_fields`). Version 18 codes
the approximation's prediction residuals in contexts of their own, of the local gradient and of
the guide channel's residual (:mod:`bandelets.coding.approximation`); the header is unchanged. This build
reads version 18 only.

Loop filter (format version 11, the squares since 12), between the streams and the CRC when byte
8 says so::

    0       1     radius of the channel's own taps (1 to MAX_FILTER_RADIUS) + 4 times the
                  radius of the square of cross-channel taps (0 none, 1: 3 x 3, 2: 5 x 5; 2 or
                  3 channels only) + 16 if the own taps fill the square of their radius, not
                  the diamond (the 5 x 5 cross-channel square and the own square since 12)
    1       1     shift: a coefficient is its integer over 2**shift (0 to MAX_FILTER_SHIFT)
    2       1     width: bits of every integer (2 to MAX_FILTER_WIDTH), two's complement
    3       1     clipping of the differences: 0 none, k (1 to MAX_FILTER_CLIP) to +-T 2**(3 - k)
    4       ...   the integers of every channel's taps in turn (:func:`filter_offsets`, then
                  :func:`filter_cross_offsets` of each other channel),
                  most significant bit first, the last byte padded with zeros

The layout of a normal map's source, which the decoder returns (since version 11 it also says
how two channels are coded: equidistant coordinates for ``xyz``, ``x, y`` for the others):
``xyz`` three channels; ``xy`` two channels, ``x, y`` (z rebuilt); ``rg`` three channels of which
only R and G were normal components (a BC5-style map whose blue holds something else, such as
ambient occlusion): the decoder returns ``x, y, z``. The layouts other than ``xyz`` were added
within version 6: a file of layout ``xyz`` is read by every version 6 decoder.

Geometry-image options (format version 2), right after the header's LEB128 integers in a file of
kind 2::

    0       1     wavelet boundary extension: EXTENSION_CODES
                  (0 symmetric, 1 spherical: cdf97, square, side a multiple of 2**levels),
                  plus 2 if the local frames are on (:mod:`bandelets.transform.frames`)
    1       4     weight of the normal component (float32; 1 when the frames are off)
    5       ...   vertices of the mesh the image was sampled from (LEB128, format version 8; 0:
                  none, else at least 4): the vertex count the mesh decoder aims at by default

Every field is validated before anything is allocated; :class:`FormatError` (a ``ValueError``)
names what is wrong. Beyond the size limits, :func:`bandelets.format.limits.check_memory` refuses a file
whose decoding would need more than ``max_memory`` bytes: a few bytes of range-coded zeros can
legitimately describe a huge image, so the size of the file says nothing about the work it asks for.

This module imports nothing from the package: it owns the codes written to disk
(:data:`KIND_CODES`, :data:`WAVELET_CODES`, ...) and the bounds of the fields, and the
algorithms take their names from it; the command line reads it without loading numba.
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Literal

__all__ = [
    "MAX_LIFTING",
    "FORMAT_VERSION",
    "TILED_CODE",
    "KIND_CODES",
    "TRANSFORM_CODES",
    "WAVELET_CODES",
    "TRANSFORM_1D_CODES",
    "EXTENSION_CODES",
    "LAYOUT_CODES",
    "KINDS",
    "TRANSFORMS",
    "LOSSLESS",
    "WAVELETS",
    "TRANSFORMS_1D",
    "EXTENSIONS",
    "LAYOUTS",
    "Kind",
    "Layout",
    "Wavelet",
    "Transform1D",
    "DEFAULT_WAVELET",
    "DEFAULT_TRANSFORM_1D",
    "DEFAULT_NORMAL_WEIGHT",
    "MAX_LEVELS",
    "MAX_RESTORATION",
    "MAX_FILTER_RADIUS",
    "MAX_FILTER_SHIFT",
    "MAX_FILTER_WIDTH",
    "MAX_FILTER_CLIP",
    "LoopFilter",
    "MAX_FILTER_CROSS",
    "filter_cross_offsets",
    "filter_offsets",
    "filter_taps",
    "filter_bytes",
    "filter_width",
    "NORMAL_MAP_WEIGHT",
    "MIN_NORMAL_WEIGHT",
    "MAX_NORMAL_WEIGHT",
    "MAX_SIDE",
    "MAX_SAMPLES",
    "MAX_MEMORY",
    "MAX_WORK",
    "MIN_THRESHOLD",
    "MAX_THRESHOLD",
    "streams_offset",
    "FormatError",
    "HEADER_BYTES",
    "Header",
    "pack",
    "unpack",
]

MAGIC = b"BDL\x1a"
FORMAT_VERSION = 18
#: The byte where a file of one tile has its kind, in a tiled file (:mod:`bandelets.codec.tiles`).
TILED_CODE = 255

class Kind(StrEnum):
    """What a file's values are (its kind field); the API and the command line take the strings."""

    #: Any image: values as they are.
    IMAGE = "image"
    #: Unit normals, renormalised before coding and after decoding (:mod:`bandelets.codec.normalmaps`).
    NORMAL_MAP = "normal-map"
    #: Positions of a surface sampled on a grid (:mod:`bandelets.surfaces`).
    GEOMETRY_IMAGE = "geometry-image"


class Layout(StrEnum):
    """How a normal map's channels are laid out in the source and in the decoded array."""

    #: Three channels ``x, y, z``.
    XYZ = "xyz"
    #: Two channels ``x, y`` (a BC5-style map), or three whose third is no normal component.
    XY = "xy"
    #: Red and green of an image hold ``x, y``.
    RG = "rg"


# The code written to disk for each choice. The codes are the format: never renumber one, only
# add new names (and say so in FORMAT_VERSION). The algorithms take their names from here.
KIND_CODES = {Kind.IMAGE: 0, Kind.NORMAL_MAP: 1, Kind.GEOMETRY_IMAGE: 2}
TRANSFORM_CODES = {"bandelet": 0, "wavelet": 1, "lossless": 2}
#: The transform of a lossless file (:mod:`bandelets.coding.lossless`): not a choice of the lossy coder.
LOSSLESS = "lossless"
#: Wavelets (:mod:`bandelets.transform.wavelets`).
WAVELET_CODES = {"cdf97": 0, "haar": 1, "db2": 2, "db4": 3, "db6": 4, "db8": 5}
#: 1D transforms along the directions (:mod:`bandelets.transform.bandeletize`).
TRANSFORM_1D_CODES = {"haar": 0, "alpert2": 1}
#: Boundary extensions of ``cdf97`` (geometry images only).
EXTENSION_CODES = {"symmetric": 0, "spherical": 1}
#: Layouts of a normal map's source (see above): ``xy`` and ``rg`` are coded as two channels.
LAYOUT_CODES = {Layout.XYZ: 0, Layout.XY: 1, Layout.RG: 2}
#: Sample depths of the source (0: float), for decoding back to them.
DEPTH_CODES = {0: 0, 8: 1, 16: 2}
KINDS, WAVELETS, TRANSFORMS_1D, EXTENSIONS, LAYOUTS = map(
    tuple, (KIND_CODES, WAVELET_CODES, TRANSFORM_1D_CODES, EXTENSION_CODES, LAYOUT_CODES)
)
#: The transforms of the lossy coder (``encode(transform=...)``).
TRANSFORMS = tuple(t for t in TRANSFORM_CODES if t != LOSSLESS)
# The same names as types, for signatures (tests/test_bitstream.py checks they agree).
Wavelet = Literal["cdf97", "haar", "db2", "db4", "db6", "db8"]
Transform1D = Literal["haar", "alpert2"]
_KIND_OF, _TRANSFORM_OF, _WAVELET_OF, _TRANSFORM_1D_OF, _EXTENSION_OF, _LAYOUT_OF = (
    {code: name for name, code in codes.items()}
    for codes in (
        KIND_CODES,
        TRANSFORM_CODES,
        WAVELET_CODES,
        TRANSFORM_1D_CODES,
        EXTENSION_CODES,
        LAYOUT_CODES,
    )
)
_DEPTH_OF = {code: depth for depth, code in DEPTH_CODES.items()}

#: The encoder's defaults (:class:`bandelets.codec.options.EncodeOptions`): the wavelet, the 1D transform,
#: and the weight of the normal component of a geometry image in local frames.
DEFAULT_WAVELET = "cdf97"
DEFAULT_TRANSFORM_1D = "alpert2"
DEFAULT_NORMAL_WEIGHT = 2.0

#: Most wavelet decomposition levels a file may have.
MAX_LEVELS = 6
#: Most wavelet levels a file may lift along directions (:mod:`bandelets.transform.directional`).
MAX_LIFTING = 3
#: Most restoration iterations a file may ask for (one byte; :mod:`bandelets.restore.restoration`).
MAX_RESTORATION = 100
#: Bounds of the loop filter (:class:`LoopFilter`): at most 24 + 2 x 12 taps per channel.
MAX_FILTER_RADIUS, MAX_FILTER_CROSS, MAX_FILTER_SHIFT, MAX_FILTER_WIDTH, MAX_FILTER_CLIP = 3, 2, 24, 24, 16
#: Weight of the normal component of the details of a normal map of three channels, coded in
#: local frames (implied by the kind and the channel count: no header field; chosen in
#: :mod:`bandelets.transform.frames`).
NORMAL_MAP_WEIGHT = 0.35
#: Largest side and sample count a decoder accepts by default.
MAX_SIDE = 16384
MAX_SAMPLES = 2**28
#: Largest working set, in bytes, the decoder (and the encoder) accepts by default
#: (:mod:`bandelets.format.limits`).
MAX_MEMORY = 2 * 2**30
#: Most restoration work the decoder (and the encoder) accepts by default
#: (:func:`bandelets.format.limits.restoration_work`): all 100 iterations up to 1024 x 1024 x 2 samples,
#: 31 at 2048 x 2048 x 2. The slowest file it lets through took 17.5 s of CPU time
#: (``benchmarks/worst_decode.py``, 2048 x 2048 x 1 restored 63 times, 65 ns per sample and
#: iteration; 1024 x 1024 x 1 restored 100 times: 5.2 s).
MAX_WORK = 2**28
#: Range of the threshold a file may hold: powers of two within the normal float32 numbers (the
#: threshold is a float32 on disk), so the restoration's smoothing, ``(0.01 T)**2``, stays a
#: normal float64, the squares of the largest values (``2**30 T``) stay finite, and no image in
#: any unit needs a finer or a coarser step (about 7.5e-37 to 1.3e36).
MIN_THRESHOLD, MAX_THRESHOLD = 2.0**-120, 2.0**120

#: Magic, version, kind, the two bytes of codes, restoration, lifting, threshold (then the five
#: LEB128 integers).
_FIXED = struct.Struct("<4sBBBBBBf")
#: Most bytes of an LEB128 integer (below 2**32).
_MOST_VARINT_BYTES = 5
#: Size of the smallest possible file: the fixed header, five one-byte integers and the CRC.
HEADER_BYTES = _FIXED.size + 5 + 4
#: Options of a geometry image: extension and frames, normal weight (then the LEB128 vertices of
#: the source mesh).
_GEOMETRY = struct.Struct("<Bf")
#: Range of the normal weight a file may hold.
MIN_NORMAL_WEIGHT, MAX_NORMAL_WEIGHT = 1 / 64, 64.0
_STREAMS = ("splits", "directions", "coefficients")


class FormatError(ValueError):
    """A .bdl file is corrupt, truncated, hostile or of an unsupported version."""


def _single(x: float) -> float:
    """``x`` rounded to the nearest float32, as the file holds it (as it is where no float32 can
    hold it: the fields' range checks then refuse it)."""
    try:
        return struct.unpack("<f", struct.pack("<f", x))[0]
    except (OverflowError, struct.error, TypeError):
        return x


def _varint(value: int) -> bytes:
    """The unsigned LEB128 bytes of ``0 <= value < 2**32``."""
    if not 0 <= value < 2**32:
        raise ValueError(f"a header integer from 0 to 2**32 - 1, not {value}")
    out = bytearray()
    while True:
        low, value = value & 127, value >> 7
        out.append(low | (128 if value else 0))
        if not value:
            return bytes(out)


def _varints(data: bytes, start: int, count: int) -> tuple[list[int], int]:
    """``count`` LEB128 integers of ``data`` from ``start``, and the offset after them."""
    values = []
    for _ in range(count):
        value = shift = 0
        for n in range(_MOST_VARINT_BYTES):
            if start >= len(data):
                raise FormatError(f"truncated .bdl file ({len(data)} bytes)")
            byte = data[start]
            start += 1
            value |= (byte & 127) << shift
            shift += 7
            if byte < 128:
                if n and not byte:
                    raise FormatError("corrupt .bdl file: an integer of the header has a needless byte")
                break
        else:
            raise FormatError("corrupt .bdl file: an integer of the header runs over 5 bytes")
        if value >= 2**32:
            raise FormatError("corrupt .bdl file: an integer of the header exceeds 2**32 - 1")
        values.append(value)
    return values, start


@dataclass(frozen=True, kw_only=True)
class LoopFilter:
    """The loop filter a file holds (:mod:`bandelets.restore.loopfilter`): the shape of every channel's
    filter and its coefficients, ``coefficients[c * n + t] / 2**shift`` for tap ``t`` of channel
    ``c``."""

    radius: int
    #: Radius of the square of taps on every other channel (0: none, 1: 3 x 3, 2: 5 x 5).
    cross: int
    #: Clipping of the differences: 0 none, ``k`` >= 1 to ``+-T 2**(3 - k)``.
    clip: int
    shift: int
    coefficients: tuple[int, ...]
    #: The channel's own taps fill the square of ``radius``, not the diamond.
    square: bool = False


def filter_offsets(radius: int, square: bool = False) -> tuple[tuple[int, int], ...]:
    """The offsets ``(dy, dx) > (0, 0)`` of the diamond ``|dy| + |dx| <= radius`` (2, 6, 12 for
    radius 1, 2, 3) or of the square ``|dy|, |dx| <= radius`` (4, 12, 24), in row order: one per
    pair of point-symmetric taps of a loop filter."""
    return tuple(
        (dy, dx)
        for dy in range(radius + 1)
        for dx in range(-radius, radius + 1)
        if (square or abs(dy) + abs(dx) <= radius) and (dy, dx) > (0, 0)
    )


def filter_cross_offsets(cross: int) -> tuple[tuple[int, int], ...]:
    """The offsets ``(dy, dx) > (0, 0)`` of the square ``|dy|, |dx| <= cross``, in row order: one
    per pair of point-symmetric taps of a loop filter on every other channel (0, 4, 12 for
    ``cross`` 0, 1, 2)."""
    return filter_offsets(cross, square=True)


def filter_taps(radius: int, cross: int, channels: int, square: bool = False) -> int:
    """Taps of one channel's loop filter: its own (:func:`filter_offsets`), then the other
    channels' (``cross``)."""
    return len(filter_offsets(radius, square)) + len(filter_cross_offsets(cross)) * (channels - 1)


def filter_width(largest: int) -> int:
    """Bits of a two's complement integer that holds ``-largest`` to ``largest`` (at least 2)."""
    return max(int(largest).bit_length() + 1, 2)


def filter_bytes(channels: int, taps: int, width: int) -> int:
    """Bytes of a loop filter section of ``taps`` integers of ``width`` bits per channel."""
    return 4 + (channels * taps * width + 7) // 8


def _most_filter_bytes(channels: int) -> int:
    """The largest loop filter section of ``channels`` channels: the 7 x 7 square of own taps, with
    cross-channel taps over the 5 x 5 square for 2 or 3 channels, at MAX_FILTER_WIDTH bits."""
    cross = MAX_FILTER_CROSS if 2 <= channels <= 3 else 0
    return filter_bytes(channels, filter_taps(MAX_FILTER_RADIUS, cross, channels, True), MAX_FILTER_WIDTH)


def _pack_filter(loop_filter: LoopFilter, channels: int) -> bytes:
    """The loop filter section (see the module's docstring)."""
    f = loop_filter
    taps = filter_taps(f.radius, f.cross, channels, f.square)
    if not (
        1 <= f.radius <= MAX_FILTER_RADIUS
        and 0 <= f.cross <= MAX_FILTER_CROSS
        and (not f.cross or 2 <= channels <= 3)
        and 0 <= f.shift <= MAX_FILTER_SHIFT
        and 0 <= f.clip <= MAX_FILTER_CLIP
        and len(f.coefficients) == channels * taps
    ):
        raise ValueError(f"not a loop filter of {channels} channels: {f}")
    width = filter_width(max((abs(v) for v in f.coefficients), default=0))
    if width > MAX_FILTER_WIDTH:
        raise ValueError(f"loop filter coefficients of more than {MAX_FILTER_WIDTH} bits: {f}")
    bits = "".join(format(v & ((1 << width) - 1), f"0{width}b") for v in f.coefficients)
    bits += "0" * (-len(bits) % 8)
    return bytes([f.radius + 4 * f.cross + 16 * f.square, f.shift, width, f.clip]) + int(
        bits or "0", 2
    ).to_bytes(len(bits) // 8, "big")


def _unpack_filter(section: bytes, channels: int) -> LoopFilter:
    """The validated loop filter of a section (:class:`FormatError` when it is not one)."""
    if len(section) < 4:
        raise FormatError(f"corrupt .bdl file: a loop filter section of {len(section)} bytes")
    shape, shift, width, clip = section[:4]
    radius, cross, square = shape % 4, shape // 4 % 4, shape // 16
    checks = [
        (
            1 <= radius <= MAX_FILTER_RADIUS and cross <= MAX_FILTER_CROSS and square <= 1,
            f"bad loop filter shape {shape}",
        ),
        (not cross or 2 <= channels <= 3, f"cross-channel loop filter taps with {channels} channels"),
        (shift <= MAX_FILTER_SHIFT, f"loop filter shift {shift} (at most {MAX_FILTER_SHIFT})"),
        (2 <= width <= MAX_FILTER_WIDTH, f"loop filter coefficients of {width} bits"),
        (clip <= MAX_FILTER_CLIP, f"loop filter clipping {clip} (at most {MAX_FILTER_CLIP})"),
    ]
    for ok, message in checks:
        if not ok:
            raise FormatError(f"corrupt .bdl file: {message}")
    count = channels * filter_taps(radius, cross, channels, bool(square))
    if len(section) != filter_bytes(channels, count // channels, width):
        raise FormatError(
            f"corrupt .bdl file: a loop filter of {count} coefficients of {width} bits "
            f"in {len(section)} bytes"
        )
    value, total = int.from_bytes(section[4:], "big"), 8 * (len(section) - 4)
    coefficients = []
    for k in range(count):
        v = (value >> (total - (k + 1) * width)) & ((1 << width) - 1)
        coefficients.append(v - (1 << width) if v >> (width - 1) else v)
    return LoopFilter(
        radius=radius,
        cross=cross,
        clip=clip,
        shift=shift,
        coefficients=tuple(coefficients),
        square=bool(square),
    )


@dataclass(frozen=True, kw_only=True)
class Header:
    """Everything a .bdl file says before its streams (built by keywords)."""

    height: int
    width: int
    channels: int
    kind: Kind
    transform: str
    wavelet: Wavelet
    levels: int
    threshold: float
    depth: int = 0
    transform_1d: Transform1D = DEFAULT_TRANSFORM_1D
    # Geometry images (the defaults for any other kind, except frames with NORMAL_MAP_WEIGHT for a
    # normal map of three channels):
    extension: str = "symmetric"
    frames: bool = False
    normal_weight: float = 1.0
    #: Vertices of the mesh a geometry image was sampled from (0: none, or not a geometry image).
    mesh_vertices: int = 0
    #: Iterations of :func:`bandelets.restore.restoration.iterate` the decoder runs (0: none).
    restoration: int = 0
    #: Layout of a normal map's source (:data:`LAYOUTS`), which the decoder returns.
    layout: Layout = Layout.XYZ
    #: Finest wavelet levels lifted along directions (:mod:`bandelets.transform.directional`; 0: none).
    lifting: int = 0
    #: The loop filter the decoder applies after the restoration (:mod:`bandelets.restore.loopfilter`).
    loop_filter: LoopFilter | None = None
    #: A normal map of three channels that is an octahedral geometry image, glued across its border
    #: (:func:`bandelets.codec.normalmaps.octahedral`; format version 14): the restoration works across the
    #: folds. A geometry image says so by its spherical extension instead.
    folded: bool = False
    #: A normal map of two channels coded as their Riesz pair (:mod:`bandelets.transform.riesz`; format version
    #: 15): 0 not, else the ``sign`` of :func:`bandelets.transform.riesz.forward` (1 or -1).
    riesz: int = 0

    def __post_init__(self) -> None:
        # The file holds the threshold and the normal weight as float32s (format version 17): a
        # header holds them so from the start, so that the encoder quantizes with the threshold
        # the decoder reads.
        # (A normal map's weight is implied, not stored: it stays as NORMAL_MAP_WEIGHT says.)
        object.__setattr__(self, "threshold", _single(self.threshold))
        if self.kind == "geometry-image":
            object.__setattr__(self, "normal_weight", _single(self.normal_weight))


def implied_options(kind: str, channels: int) -> dict:
    """The fields of :class:`Header` that the file does not store for ``kind`` (any kind but a
    geometry image) and ``channels``: local frames for a normal map of three channels."""
    if kind == "normal-map" and channels == 3:
        return {"frames": True, "normal_weight": NORMAL_MAP_WEIGHT}
    return {}


def streams_offset(data: bytes) -> int:
    """Offset of the first stream of a file (after its header, and the options of a geometry
    image): :class:`FormatError` where its header is cut short or its integers malformed."""
    if len(data) < _FIXED.size:
        raise FormatError(f"truncated .bdl file ({len(data)} bytes)")
    start = _varints(data, _FIXED.size, 5)[1]
    if data[5] == KIND_CODES["geometry-image"]:
        start = _varints(data, start + _GEOMETRY.size, 1)[1]
    return start


def pack(header: Header, streams: tuple[bytes, bytes, bytes]) -> bytes:
    """Assemble a .bdl file from its header and its three coded streams.

    Examples
    --------
    >>> header = Header(
    ...     height=4, width=6, channels=1, kind="image", transform="bandelet", wavelet="cdf97", levels=1,
    ...     threshold=0.5,
    ... )
    >>> data = pack(header, (b"", b"", b"ab"))
    >>> len(data) == HEADER_BYTES + 2
    True
    >>> unpack(data) == (header, (b"", b"", b"ab"))
    True
    """
    # Values that would run into the next field's bits (the decoder checks the others' meaning).
    if not (
        0 <= header.levels < 8
        and 1 <= header.channels <= 4
        and header.depth in DEPTH_CODES
        and 0 <= header.restoration < 128
        and 0 <= header.lifting < 32
    ):
        raise ValueError(f"levels, channels, depth, restoration or lifting out of range: {header}")
    if not MIN_THRESHOLD <= header.threshold <= MAX_THRESHOLD:
        raise ValueError(f"threshold must be from {MIN_THRESHOLD:g} to {MAX_THRESHOLD:g}: {header}")
    if header.threshold != _single(header.threshold):  # the encoder quantized with another T
        raise ValueError(f"a threshold that is no float32 (Header rounds it): {header}")
    body = _FIXED.pack(
        MAGIC,
        FORMAT_VERSION,
        KIND_CODES[header.kind],
        TRANSFORM_CODES[header.transform]
        + 4 * WAVELET_CODES[header.wavelet]
        + 32 * TRANSFORM_1D_CODES[header.transform_1d]
        + 64 * LAYOUT_CODES[header.layout],
        header.levels + 8 * (header.channels - 1) + 32 * DEPTH_CODES[header.depth],
        header.restoration + (128 if header.loop_filter is not None else 0),
        header.lifting + _riesz_code(header.riesz) + (128 if header.folded else 0),
        header.threshold,
    )
    body += b"".join(_varint(n) for n in (header.height, header.width, *map(len, streams)))
    if header.layout != "xyz" and (header.kind, header.channels) != ("normal-map", 2):
        raise ValueError(f"layout {header.layout!r} is for normal maps coded as x, y: {header}")
    if header.folded and not _can_fold(
        header.kind, header.channels, header.transform, header.levels, header.height, header.width
    ):
        raise ValueError(f"only a square normal map of 3 channels, unpadded, can be folded: {header}")
    if header.riesz and not _can_turn(header.kind, header.channels, header.transform):
        raise ValueError(f"only a lossy normal map of 2 channels can be coded as its Riesz pair: {header}")
    if header.kind != "geometry-image":  # its options are not stored, so they must be the implied ones
        defaults = {
            "extension": Header.extension,
            "frames": Header.frames,
            "normal_weight": Header.normal_weight,
            "mesh_vertices": Header.mesh_vertices,
        }
        if header != replace(header, **(defaults | implied_options(header.kind, header.channels))):
            raise ValueError(
                f"a {header.kind} of {header.channels} channels has no choice of extension, frames, "
                f"normal weight or mesh vertices: {header}"
            )
    if header.kind == "geometry-image":
        body += _GEOMETRY.pack(EXTENSION_CODES[header.extension] + 2 * header.frames, header.normal_weight)
        body += _varint(header.mesh_vertices)
    body += b"".join(streams)
    if header.loop_filter is not None:
        body += _pack_filter(header.loop_filter, header.channels)
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
    if len(data) < HEADER_BYTES:
        raise FormatError(f"truncated .bdl file ({len(data)} bytes)")
    fields = _FIXED.unpack_from(data)
    version = fields[1]
    if version != FORMAT_VERSION:
        raise FormatError(
            f".bdl format version {version} is not supported (this build reads version {FORMAT_VERSION})"
        )
    if fields[2] == TILED_CODE:
        raise FormatError("a tiled .bdl file: read it whole with bandelets.decode (bandelets.codec.tiles)")
    body, crc = data[:-4], struct.unpack("<I", data[-4:])[0]
    if zlib.crc32(body) != crc:
        raise FormatError("corrupt .bdl file (CRC32 mismatch)")
    kind_code, codes, sizes, restoration, lifting_byte, threshold = fields[2:]
    (height, width, *lengths), start = _varints(body, _FIXED.size, 5)
    transform_code, wavelet_code, along_code, layout_code = (
        codes % 4,
        codes // 4 % 8,
        codes // 32 % 2,
        codes // 64,
    )
    levels, channels, depth_code = sizes % 8, sizes // 8 % 4 + 1, sizes // 32
    restoration, filtered = restoration % 128, restoration // 128
    lifting, riesz, folded = lifting_byte % 32, _RIESZ_OF.get(lifting_byte // 32 % 4), lifting_byte // 128
    depth = _DEPTH_OF.get(depth_code)
    layout = _LAYOUT_OF.get(layout_code)
    kind, transform = _KIND_OF.get(kind_code), _TRANSFORM_OF.get(transform_code)
    wavelet, along = _WAVELET_OF.get(wavelet_code), _TRANSFORM_1D_OF.get(along_code)
    if kind == "geometry-image":
        if len(body) < start + _GEOMETRY.size:
            raise FormatError(f"truncated .bdl file ({len(data)} bytes)")
        stored = _GEOMETRY.unpack_from(body, start)
        (vertices,), start = _varints(body, start + _GEOMETRY.size, 1)
    checks = [
        (kind is not None, f"unknown kind code {kind_code}"),
        (
            kind in (None, "image") or channels == 3 or (kind == "normal-map" and channels == 2),
            f"a {kind} needs 3 channels{' (or 2)' if kind == 'normal-map' else ''}, the file has {channels}",
        ),
        (transform is not None, f"unknown transform code {transform_code}"),
        (wavelet is not None, f"unknown wavelet code {wavelet_code}"),
        (depth is not None, f"bad sample depth code {depth_code}"),
        (
            layout == "xyz" or (layout is not None and kind == "normal-map" and channels == 2),
            f"bad layout code {layout_code} for a {kind} of {channels} channels",
        ),
        (along is not None, f"unknown 1D transform code {along_code}"),
        (
            1 <= height <= max_side and 1 <= width <= max_side,
            f"image size {width} x {height} exceeds the limit of {max_side} per side",
        ),
        (
            height * width * channels <= max_samples,
            f"image of {height * width * channels} samples exceeds the limit of {max_samples}",
        ),
        (MIN_THRESHOLD <= threshold <= MAX_THRESHOLD, f"bad threshold {threshold}"),
        (restoration <= MAX_RESTORATION, f"{restoration} restoration iterations (at most {MAX_RESTORATION})"),
        (
            0 < len(body) - start - sum(lengths) <= _most_filter_bytes(channels)
            if filtered
            else sum(lengths) == len(body) - start,
            "stream lengths do not match the file size",
        ),
        (
            lifting == 0 or (wavelet == "cdf97" and kind != "geometry-image"),
            f"directional lifting of a {kind} of {channels} channels, wavelet {wavelet}",
        ),
        (
            not folded or _can_fold(kind, channels, transform, levels, height, width),
            f"a folded {kind} of {channels} channels, {width} x {height} at {levels} levels",
        ),
        (
            riesz is not None and (not riesz or _can_turn(kind, channels, transform)),
            f"Riesz code {lifting_byte // 32 % 4} for a {kind} of {channels} channels ({transform})",
        ),
        (
            lifting <= min(levels, MAX_LIFTING),
            f"{lifting} directional levels (at most {MAX_LIFTING}, {levels} levels)",
        ),
        (
            transform != LOSSLESS
            or (
                depth in (8, 16)
                and kind != "geometry-image"
                and (levels, threshold, restoration, filtered, lifting) == (1, 1.0, 0, 0, 0)
                and lengths[0] == lengths[1] == 0
            ),
            f"a lossless file of depth {depth} with lossy fields (levels, threshold, restoration, "
            "loop filter, lifting or geometry streams)",
        ),
    ]
    for ok, message in checks:
        if not ok:
            raise FormatError(f"corrupt .bdl file: {message}")
    if not 1 <= levels <= MAX_LEVELS:
        raise FormatError(f"corrupt .bdl file: bad number of wavelet levels {levels}")
    if kind == "geometry-image":
        options = _geometry_options(*stored, vertices, wavelet, levels, height, width)
    else:
        options = implied_options(kind, channels)
    loop_filter = _unpack_filter(body[start + sum(lengths) :], channels) if filtered else None
    header = Header(
        height=height,
        width=width,
        channels=channels,
        kind=kind,
        transform=transform,
        wavelet=wavelet,
        levels=levels,
        threshold=threshold,
        depth=depth,
        transform_1d=along,
        **options,
        restoration=restoration,
        layout=layout,
        lifting=lifting,
        loop_filter=loop_filter,
        folded=bool(folded),
        riesz=riesz,
    )
    streams = []
    for n in lengths:
        streams.append(bytes(data[start : start + n]))
        start += n
    return header, tuple(streams)


#: Byte 9's Riesz bits (32 on, 64 rows against the slope) of each :attr:`Header.riesz`.
_RIESZ_CODES = {0: 0, 1: 1, -1: 3}
_RIESZ_OF = {code: sign for sign, code in _RIESZ_CODES.items()}


def _riesz_code(riesz: int) -> int:
    if riesz not in _RIESZ_CODES:
        raise ValueError(f"Header.riesz is 0, 1 or -1, not {riesz!r}")
    return 32 * _RIESZ_CODES[riesz]


def _can_turn(kind: str, channels: int, transform: str) -> bool:
    """Whether a file of these fields may be coded as a Riesz pair (:attr:`Header.riesz`)."""
    return kind == "normal-map" and channels == 2 and transform != LOSSLESS


def _can_fold(kind: str, channels: int, transform: str, levels: int, height: int, width: int) -> bool:
    """Whether a file of these fields may be folded (:attr:`Header.folded`): a lossy normal map of
    three channels, square, its side a multiple of ``2**levels`` (not padded: the folds are the
    border of the image the restoration sees)."""
    return (
        kind == "normal-map"
        and channels == 3
        and transform != LOSSLESS
        and height == width
        and height % (1 << levels) == 0
    )


def _geometry_options(
    extension: int, weight: float, vertices: int, wavelet: str, levels: int, height: int, width: int
) -> dict:
    """Validated geometry-image options of a file, as stored (its fixed header already validated)."""
    frames = extension // 2 % 2
    extension -= 2 * frames  # bits above the frames flag make an unknown extension code
    checks = [
        (extension in _EXTENSION_OF, f"unknown extension code {extension}"),
        (
            bool(frames) or weight == 1.0,
            f"normal weight {weight} without local frames",
        ),
        (
            math.isfinite(weight) and MIN_NORMAL_WEIGHT <= weight <= MAX_NORMAL_WEIGHT,
            f"bad normal weight {weight}",
        ),
        (
            extension != EXTENSION_CODES["spherical"]
            or (wavelet == "cdf97" and height == width and height % (1 << levels) == 0),
            f"spherical extension of a {width} x {height} {wavelet} image at {levels} levels",
        ),
        (vertices == 0 or vertices >= 4, f"a source mesh of {vertices} vertices"),
    ]
    for ok, message in checks:
        if not ok:
            raise FormatError(f"corrupt .bdl file: {message}")
    return {
        "extension": _EXTENSION_OF[extension],
        "frames": bool(frames),
        "normal_weight": weight,
        "mesh_vertices": vertices,
    }


def padded_shape(shape: tuple[int, int], levels: int) -> tuple[int, int]:
    """Size of a channel once padded to a multiple of ``2**levels`` on both sides."""
    step = 1 << levels
    return tuple(-(-side // step) * step for side in shape)
