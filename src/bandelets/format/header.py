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
                  samples, for decoding back to them), plus 128 if a normal map's green channel
                  points down (DirectX; format version 19; 0: up, OpenGL)
    8       1     restoration iterations, 0 to 100 (0: off; :mod:`bandelets.restore.restoration`), plus 128
                  if the file has a loop filter (format version 11)
    9       1     finest wavelet levels lifted along directions (0: none;
                  :mod:`bandelets.transform.directional`), plus 32 if the two channels of a normal map
                  are coded as their Riesz pair,
                  64 more if its rows run against the slope (format version 15, see below),
                  plus 128 if the image is folded (format version 14, see below)
    10      4     threshold T (float32, MIN_THRESHOLD to MAX_THRESHOLD)
    14      ...   height, width, then the byte lengths of the segments of the three streams
                  (quadtree splits, directions, coefficients) of each group of levels, group by
                  group (format version 19, :mod:`bandelets.format.levels`; group 0 its
                  coefficients' alone): ``3 levels + 1`` unsigned LEB128 integers (7 bits a byte, low
                  bits first, the top bit set on every byte but the last; at most 5 bytes, no
                  needless trailing byte, below 2**32)
    ...     ...   geometry-image options (kind 2 only, see below)
    ...     ...   the segments, group by group (coarse to fine), each group's three in order
    ...     ...   the loop filter (format version 11; when byte 8 says so; :mod:`bandelets.format.filter`)
    end-4   4     CRC32 of everything before it

The history of the format's versions is in ``docs/history.md``; this build reads version 19 only.

The layout of a normal map's source, which the decoder returns (since version 11 it also says
how two channels are coded: equidistant coordinates for ``xyz``, ``x, y`` for the others):
``xyz`` three channels; ``xy`` two channels, ``x, y`` (z rebuilt); ``rg`` three channels of which
only R and G were normal components (a BC5-style map whose blue holds something else, such as
ambient occlusion): the decoder returns ``x, y, z``. The layouts other than ``xyz`` were added
within version 6: a file of layout ``xyz`` is read by every version 6 decoder. Within version 19 an
``xy`` or ``rg`` map may be coded as ``x, y, z`` (``box_mips``): it decodes to its layout all the same.

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

The codes written to disk and the bounds of the fields are :mod:`bandelets.format.fields`, the
loop filter's section :mod:`bandelets.format.filter`; nothing here loads numba, so the command line
reads headers fast.
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass, replace

from .fields import (
    DEFAULT_TRANSFORM_1D,
    DEPTH_CODES,
    EXTENSION_CODES,
    FORMAT_VERSION,
    KIND_CODES,
    LAYOUT_CODES,
    LOSSLESS,
    MAGIC,
    MAX_LEVELS,
    MAX_LIFTING,
    MAX_NORMAL_WEIGHT,
    MAX_RESTORATION,
    MAX_SAMPLES,
    MAX_SIDE,
    MAX_THRESHOLD,
    MIN_NORMAL_WEIGHT,
    MIN_THRESHOLD,
    NORMAL_MAP_WEIGHT,
    TILED_CODE,
    TRANSFORM_1D_CODES,
    TRANSFORM_CODES,
    WAVELET_CODES,
    FormatError,
    Kind,
    Layout,
    Transform1D,
    Wavelet,
)
from .filter import LoopFilter, most_filter_bytes, pack_filter, unpack_filter
from .levels import group_count, interleave, segment_lengths, split, stored_lengths
from .varint import varint

__all__ = ["HEADER_BYTES", "Header", "implied_options", "pack", "streams_offset", "unpack"]


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


#: Magic, version, kind, the two bytes of codes, restoration, lifting, threshold (then the five
#: LEB128 integers).
_FIXED = struct.Struct("<4sBBBBBBf")
#: Most bytes of an LEB128 integer (below 2**32).
_MOST_VARINT_BYTES = 5
#: Size of the smallest possible file: the fixed header, five one-byte integers (a lossless file) and the CRC.
HEADER_BYTES = _FIXED.size + 5 + 4
#: The green conventions of a normal map (byte 7's top bit: 0 up, OpenGL; 1 down, DirectX).
GREENS = ("up", "down")
#: Options of a geometry image: extension and frames, normal weight (then the LEB128 vertices of
#: the source mesh).
_GEOMETRY = struct.Struct("<Bf")
_STREAMS = ("splits", "directions", "coefficients")


def _single(x: float) -> float:
    """``x`` rounded to the nearest float32, as the file holds it (as it is where no float32 can
    hold it: the fields' range checks then refuse it)."""
    try:
        return struct.unpack("<f", struct.pack("<f", x))[0]
    except (OverflowError, struct.error, TypeError):
        return x


def _varint(value: int) -> bytes:
    """The unsigned LEB128 bytes of ``0 <= value < 2**32`` (:func:`bandelets.format.varint.varint`)."""
    if not 0 <= value < 2**32:
        raise ValueError(f"a header integer from 0 to 2**32 - 1, not {value}")
    return varint(value)


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
    #: A normal map of two channels coded as their Riesz pair (:mod:`bandelets.transform.riesz`; format
    #: version
    #: 15): 0 not, else the ``sign`` of :func:`bandelets.transform.riesz.forward` (1 or -1).
    riesz: int = 0
    #: The byte lengths of the segments of the three streams, group by group (format version 19,
    #: :mod:`bandelets.format.levels`); empty: every byte in the last group.
    segments: tuple = ()
    #: Where a normal map's green channel (y) points: "up" (OpenGL) or "down" (DirectX); format
    #: version 19, a label the decoder keeps (``bandelets decode --green`` flips y to the other).
    green: str = "up"

    def __post_init__(self) -> None:
        # The file holds the threshold and the normal weight as float32s (format version 17): a
        # header holds them so from the start, so that the encoder quantizes with the threshold
        # the decoder reads.
        # (A normal map's weight is implied, not stored: it stays as NORMAL_MAP_WEIGHT says.)
        object.__setattr__(self, "threshold", _single(self.threshold))
        if self.kind == Kind.GEOMETRY_IMAGE:
            object.__setattr__(self, "normal_weight", _single(self.normal_weight))


def implied_options(kind: str, channels: int) -> dict:
    """The fields of :class:`Header` that the file does not store for ``kind`` (any kind but a
    geometry image) and ``channels``: local frames for a normal map of three channels."""
    if kind == Kind.NORMAL_MAP and channels == 3:
        return {"frames": True, "normal_weight": NORMAL_MAP_WEIGHT}
    return {}


def streams_offset(data: bytes) -> int:
    """Offset of the first stream of a file (after its header, and the options of a geometry
    image): :class:`FormatError` where its header is cut short or its integers malformed."""
    if len(data) < _FIXED.size:
        raise FormatError(f"truncated .bdl file ({len(data)} bytes)")
    groups = group_count(data[7] % 8, _TRANSFORM_OF.get(data[6] % 4))
    start = _varints(data, _FIXED.size, 3 * groups)[1]
    if data[5] == KIND_CODES[Kind.GEOMETRY_IMAGE]:
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
    >>> len(data) == HEADER_BYTES + 1 + 2  # six integers: the sides, 1 + 3 segment lengths
    True
    >>> unpack(data) == (replace(header, segments=((0, 0, 0), (0, 0, 2))), (b"", b"", b"ab"))
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
        header.levels + 8 * (header.channels - 1) + 32 * DEPTH_CODES[header.depth] + 128 * _green(header),
        header.restoration + (128 if header.loop_filter is not None else 0),
        header.lifting + _riesz_code(header.riesz) + (128 if header.folded else 0),
        header.threshold,
    )
    if header.layout != Layout.XYZ and (header.kind != Kind.NORMAL_MAP or header.channels not in (2, 3)):
        raise ValueError(f"layout {header.layout!r} is for normal maps: {header}")
    if header.folded and not _can_fold(
        header.kind, header.channels, header.transform, header.levels, header.height, header.width
    ):
        raise ValueError(f"only a square normal map of 3 channels, unpadded, can be folded: {header}")
    if header.riesz and not _can_turn(header.kind, header.channels, header.transform):
        raise ValueError(f"only a lossy normal map of 2 channels can be coded as its Riesz pair: {header}")
    if header.kind != Kind.GEOMETRY_IMAGE:  # its options are not stored, so they must be the implied ones
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
    segments = segment_lengths(header.levels, header.transform, header.segments, streams)
    body += b"".join(_varint(n) for n in (header.height, header.width, *stored_lengths(segments)))
    if header.kind == Kind.GEOMETRY_IMAGE:
        body += _GEOMETRY.pack(EXTENSION_CODES[header.extension] + 2 * header.frames, header.normal_weight)
        body += _varint(header.mesh_vertices)
    body += interleave(streams, segments)
    if header.loop_filter is not None:
        body += pack_filter(header.loop_filter, header.channels)
    return body + struct.pack("<I", zlib.crc32(body))


def _consistency(
    kind,
    channels,
    transform,
    wavelet,
    depth,
    layout,
    along,
    height,
    width,
    levels,
    threshold,
    restoration,
    filtered,
    lifting,
    folded,
    riesz,
    lifting_byte,
    codes: tuple[int, int, int, int, int],
    lengths,
    spare: int,
    max_side: int,
    max_samples: int,
) -> list[tuple[bool, str]]:
    """Each check :func:`unpack` makes of a header's fields, and what it says when one fails; ``codes``:
    the kind, transform, wavelet, depth and layout codes as read (None fields: unknown codes),
    ``spare``: the bytes after the header and geometry options but the CRC."""
    kind_code, transform_code, wavelet_code, depth_code, layout_code, along_code = codes
    return [
        (kind is not None, f"unknown kind code {kind_code}"),
        (
            kind in (None, "image") or channels == 3 or (kind == Kind.NORMAL_MAP and channels == 2),
            f"a {kind} needs 3 channels{' (or 2)' if kind == 'normal-map' else ''}, the file has {channels}",
        ),
        (transform is not None, f"unknown transform code {transform_code}"),
        (wavelet is not None, f"unknown wavelet code {wavelet_code}"),
        (depth is not None, f"bad sample depth code {depth_code}"),
        (
            layout == Layout.XYZ or (layout is not None and kind == Kind.NORMAL_MAP and channels in (2, 3)),
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
            lifting == 0 or (wavelet == "cdf97" and kind != Kind.GEOMETRY_IMAGE),
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
                and kind != Kind.GEOMETRY_IMAGE
                and (levels, threshold, restoration, filtered, lifting) == (1, 1.0, 0, 0, 0)
                and lengths[0] == lengths[1] == 0
            ),
            f"a lossless file of depth {depth} with lossy fields (levels, threshold, restoration, "
            "loop filter, lifting or geometry streams)",
        ),
        # Last: a field patched to another count of levels or transform reads other integers (format 19).
        (
            0 < spare - sum(lengths) <= most_filter_bytes(channels) if filtered else sum(lengths) == spare,
            "stream lengths do not match the file size",
        ),
    ]


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
    header, parts = unpack_prefix(data, whole=True, max_side=max_side, max_samples=max_samples)
    return header, tuple(b"".join(p) for p in parts)


def unpack_prefix(
    data: bytes, *, whole: bool = False, max_side: int = MAX_SIDE, max_samples: int = MAX_SAMPLES
) -> tuple[Header, tuple[list[bytes], list[bytes], list[bytes]]]:
    """The header of a .bdl file or a prefix of one (``whole``: the file) and the segments of each stream
    (:mod:`bandelets.format.levels`) of the groups it holds in whole. A prefix has no CRC (it is at the
    end) and no loop filter read; its header is checked as a whole file's."""
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
        raise FormatError(
            "a tiled .bdl file: read it whole with bandelets.decode (bandelets.format.container)"
        )
    body, crc = data[:-4], struct.unpack("<I", data[-4:])[0]
    complete = zlib.crc32(body) == crc
    if whole and not complete:
        raise FormatError("corrupt .bdl file (CRC32 mismatch)")
    if not complete:  # a prefix: every byte is the file's
        body = data
    kind_code, codes, sizes, restoration, lifting_byte, threshold = fields[2:]
    green, sizes = sizes // 128, sizes % 128
    if not 1 <= sizes % 8 <= MAX_LEVELS:  # before the integers, whose count it gives
        raise FormatError(f"corrupt .bdl file: bad number of wavelet levels {sizes % 8}")
    groups = group_count(sizes % 8, _TRANSFORM_OF.get(codes % 4))
    (height, width, *flat), start = _varints(body, _FIXED.size, 3 * groups)
    segments = ((0, 0, flat[0]),) + tuple(tuple(flat[3 * g - 2 : 3 * g + 1]) for g in range(1, groups))
    lengths = [sum(g[s] for g in segments) for s in range(3)]
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
    if kind == Kind.GEOMETRY_IMAGE:
        if len(body) < start + _GEOMETRY.size:
            raise FormatError(f"truncated .bdl file ({len(data)} bytes)")
        stored = _GEOMETRY.unpack_from(body, start)
        (vertices,), start = _varints(body, start + _GEOMETRY.size, 1)
    checks = _consistency(
        kind, channels, transform, wavelet, depth, layout, along, height, width, levels, threshold,
        restoration, filtered, lifting, folded, riesz, lifting_byte,
        (kind_code, transform_code, wavelet_code, depth_code, layout_code, along_code), lengths,
        len(body) - start if complete else sum(lengths) + (filtered and 1), max_side, max_samples,
    )  # fmt: skip
    checks.append((not green or kind == Kind.NORMAL_MAP, f"a green convention for a {kind}"))
    for ok, message in checks:
        if not ok:
            raise FormatError(f"corrupt .bdl file: {message}")
    if kind == Kind.GEOMETRY_IMAGE:
        options = _geometry_options(*stored, vertices, wavelet, levels, height, width)
    else:
        options = implied_options(kind, channels)
    loop_filter = None
    if filtered and complete:
        loop_filter = unpack_filter(body[start + sum(lengths) :], channels)
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
        segments=segments,
        green=GREENS[green],
    )
    return header, split(body, start, segments)


def _green(header: Header) -> int:
    if header.green not in GREENS or (header.green == "down" and header.kind != Kind.NORMAL_MAP):
        raise ValueError(f"green is 'up' or 'down', and 'down' for a normal map only: {header}")
    return GREENS.index(header.green)


#: Byte 9's Riesz bits (32 on, 64 rows against the slope) of each :attr:`Header.riesz`.
_RIESZ_CODES = {0: 0, 1: 1, -1: 3}
_RIESZ_OF = {code: sign for sign, code in _RIESZ_CODES.items()}


def _riesz_code(riesz: int) -> int:
    if riesz not in _RIESZ_CODES:
        raise ValueError(f"Header.riesz is 0, 1 or -1, not {riesz!r}")
    return 32 * _RIESZ_CODES[riesz]


def _can_turn(kind: str, channels: int, transform: str) -> bool:
    """Whether a file of these fields may be coded as a Riesz pair (:attr:`Header.riesz`)."""
    return kind == Kind.NORMAL_MAP and channels == 2 and transform != LOSSLESS


def _can_fold(kind: str, channels: int, transform: str, levels: int, height: int, width: int) -> bool:
    """Whether a file of these fields may be folded (:attr:`Header.folded`): a lossy normal map of
    three channels, square, its side a multiple of ``2**levels`` (not padded: the folds are the
    border of the image the restoration sees)."""
    return (
        kind == Kind.NORMAL_MAP
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
