"""The tiled container (format version 9): large images coded as independent tiles, for bounded
memory, flat time per pixel, both cores, and a decoder that can read a region.

An image with a side above the tile side (:data:`TILE`, 512 by default) is cut into a grid of
tiles, each coded as a complete .bdl file (its own quadtrees, bins and restoration, see
:mod:`bandelets.codec.encoder`), and the tiles are stored one after the other in a container::

    offset  size  field
    0       4     magic b"BDL\\x1a"
    4       1     format version (FORMAT_VERSION)
    5       1     TILED_CODE (255, where a file of one tile has its kind)
    6       2     zero
    8       4     height
    12      4     width
    16      4     tile side
    20      4 n   byte length of each of the n tiles, row by row
    20+4n   4     CRC32 of everything before it
    24+4n   ...   the tiles, each a .bdl file of one tile (with its own CRC)

A tile covers ``tile`` rows and columns from a multiple of ``tile``; the last tile of a row or
a column also takes the remainder when that is less than a quarter of a tile (no thin tiles:
:func:`cuts`). An image of one tile is a plain .bdl file, byte for byte what the untiled coder
writes.

Why tiles: the encoder's and the decoder's working sets grow with the image (about 100 bytes
per sample, :mod:`bandelets.format.limits`), the restoration's iterations and the basis search grow
faster than the pixel count at large sizes, and a 4096 x 4096 map was refused under the default
limits. Tiles bound the working set by the tiles in flight (:data:`WORKERS`), keep the time
per pixel that of a 512 x 512 map, run on both cores (a thread per tile), and let a decoder
decode only the tiles a region touches. Rate control stays global: every tile is coded at one
threshold ``T`` (one quantizer and one Lagrangian slope everywhere, the rate-distortion optimal
allocation among tiles), found by one search on the size or the quality of the whole image.
The restoration of the whole file is bounded as that of one piece: each tile's encoder restores
within its share of ``max_work`` (its share of the pixels), and the decoder refuses a file whose
tiles together ask for more than ``max_work``.

The tiles are coded independently: nothing crosses a tile border, and a smooth map pays for
each border in bits (the wavelet transform extends a tile past it symmetrically, a kink where the
surface has a slope: 15 % more bytes at one threshold for tiles of 512 on a smooth 1024 x 1024
map, BENCHMARKS.md "What tiling costs").

Written here: the container is ours. Its coding, tile by tile, is :mod:`bandelets.codec.tiled`
(encoding) and :func:`bandelets.codec.decoder.decode` (decoding).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, replace

import numpy as np

from .fields import (
    FORMAT_VERSION,
    MAGIC,
    MAX_SAMPLES,
    MAX_SIDE,
    MAX_WORK,
    TILED_CODE,
    FormatError,
    Kind,
    Layout,
)
from .header import Header, unpack

__all__ = [
    "MIN_TILE",
    "TILE",
    "TILE_WORK",
    "WORKERS",
    "Grid",
    "check_region",
    "check_tile_count",
    "cuts",
    "header_of",
    "is_tiled",
    "output_of",
    "pack",
    "read",
]


#: Default tile side: a 512 x 512 map is one tile, coded as before.
TILE = 512


#: Smallest tile side a file may have (the tests use small tiles).
MIN_TILE = 16


#: Tiles coded or decoded at once (threads): the machine's two cores.
WORKERS = 2


#: The fixed work of decoding a tile, in the units of ``max_work`` (sample-iterations of
#: restoration, :func:`bandelets.format.limits.restoration_work`), counted for every tile a decode
#: reads (issue 40): a tile costs its parsing, its range decoders and its transforms' set-up whatever
#: its size, 0.8 to 1.4 ms of CPU, so that 4,096 tiles of 16 x 16 without restoration (a 537 KB file)
#: took 4.1 s to decode, and 262,144 of them (8192 x 8192) minutes, with no restoration to bound.
#: At 2**17 the default ``max_work`` admits at most 2,048 tiles (about 2 s): a 16384 x 16384 map in
#: the default tiles of 512 (1,024 tiles) gives up half of it, an 8192 x 8192 one an eighth; smaller
#: tiles for such sizes need a larger ``max_work`` (the encoder refuses to write what the decoder
#: would refuse).
TILE_WORK = 2**17

_HEAD = struct.Struct("<4sBBxxIII")


@dataclass(frozen=True)
class Grid:
    """The tiles of a ``height`` x ``width`` image cut at ``tile``."""

    height: int
    width: int
    tile: int

    @property
    def boxes(self) -> list[tuple[slice, slice]]:
        """The (rows, columns) of each tile, row by row."""
        return [(r, c) for r in cuts(self.height, self.tile) for c in cuts(self.width, self.tile)]

    @property
    def tiled(self) -> bool:
        """More than one tile (a hostile size makes no list of boxes to find out)."""
        return self.height > self.tile + self.tile // 4 - 1 or self.width > self.tile + self.tile // 4 - 1


def cuts(size: int, tile: int) -> list[slice]:
    """The spans of the tiles along a side of ``size`` pixels: from each multiple of ``tile``,
    the last one taking the remainder when it is below ``tile / 4``."""
    starts = list(range(0, size, tile)) or [0]
    if len(starts) > 1 and size - starts[-1] < tile // 4:
        starts.pop()
    ends = starts[1:] + [size]
    return [slice(a, b) for a, b in zip(starts, ends, strict=True)]


def is_tiled(data: bytes) -> bool:
    """Whether ``data`` starts like a tiled .bdl file of this format version."""
    return len(data) >= 6 and data[:4] == MAGIC and data[4] == FORMAT_VERSION and data[5] == TILED_CODE


def pack(grid: Grid, tiles: list[bytes]) -> bytes:
    """The tiled .bdl file of ``tiles`` (.bdl files, one per box of ``grid``, row by row)."""
    head = _HEAD.pack(MAGIC, FORMAT_VERSION, TILED_CODE, grid.height, grid.width, grid.tile)
    head += struct.pack(f"<{len(tiles)}I", *(len(t) for t in tiles))
    return b"".join([head, struct.pack("<I", zlib.crc32(head)), *tiles])


def read(data: bytes, *, max_side: int = MAX_SIDE, max_samples: int = MAX_SAMPLES) -> tuple[Grid, list]:
    """The grid of a tiled .bdl file and a lazy reader of its tiles: ``tiles[i]()`` parses tile
    ``i`` (:func:`bandelets.format.header.unpack`) and checks it against the grid and the first tile.

    Raises
    ------
    FormatError
        A corrupt or truncated container (each tile is checked when it is read).
    """
    if len(data) < _HEAD.size + 4:
        raise FormatError(f"truncated .bdl file ({len(data)} bytes)")
    _, _, _, height, width, tile = _HEAD.unpack_from(data)
    if not (1 <= height <= max_side and 1 <= width <= max_side):
        raise FormatError(f"corrupt .bdl file: image size {width} x {height} exceeds the limit of {max_side}")
    if not MIN_TILE <= tile <= max_side:
        raise FormatError(f"corrupt .bdl file: tile side {tile}")
    grid = Grid(height, width, tile)
    count = len(cuts(height, tile)) * len(cuts(width, tile))
    if count < 2:
        raise FormatError(f"corrupt .bdl file: a tiled file of one {tile} x {tile} tile")
    table_end = _HEAD.size + 4 * count
    if len(data) < table_end + 4:  # before the grid's boxes are made: a few bytes may claim millions
        raise FormatError(f"truncated .bdl file ({len(data)} bytes for {count} tiles)")
    boxes = grid.boxes
    if zlib.crc32(data[:table_end]) != struct.unpack_from("<I", data, table_end)[0]:
        raise FormatError("corrupt .bdl file (CRC32 mismatch in the tile table)")
    lengths = struct.unpack_from(f"<{len(boxes)}I", data, _HEAD.size)
    starts = np.cumsum([table_end + 4, *lengths])
    if starts[-1] > len(data):
        raise FormatError(f"truncated .bdl file ({len(data)} bytes, its tiles end at byte {starts[-1]})")
    if starts[-1] < len(data):
        raise FormatError("corrupt .bdl file: tile lengths do not match the file size")
    first: list[Header] = []

    def tile_reader(i: int):
        def parse() -> tuple[Header, tuple[bytes, bytes, bytes]]:
            header, streams = unpack(
                data[starts[i] : starts[i + 1]], max_side=max_side, max_samples=max_samples
            )
            rows, cols = boxes[i]
            if (header.height, header.width) != (rows.stop - rows.start, cols.stop - cols.start):
                raise FormatError(f"corrupt .bdl file: tile {i} is {header.width} x {header.height}")
            if not first:
                if height * width * header.channels > max_samples:
                    raise FormatError(
                        f"corrupt .bdl file: image of {height * width * header.channels} samples exceeds "
                        f"the limit of {max_samples}"
                    )
                first.append(header)
            if output_of(header) != output_of(first[0]):
                raise FormatError(f"corrupt .bdl file: tile {i} is not of the kind of the first tile")
            return header, streams

        return parse

    return grid, [tile_reader(i) for i in range(len(boxes))]


def output_of(header: Header) -> tuple:
    """What a tile's decoded array is made of, which every tile of a file shares."""
    channels = 3 if header.kind == Kind.NORMAL_MAP and header.layout != Layout.XY else header.channels
    return header.kind, header.layout, header.depth, channels


def header_of(data: bytes, max_work: int = MAX_WORK, **limits) -> Header:
    """The header of a .bdl file, tiled or not: for a tiled file, that of its first tile with the
    whole image's size and the most restoration iterations of any tile (refused, as by
    :func:`bandelets.decode`, when its tiles are more than ``max_work`` allows: every tile is parsed)."""
    if not is_tiled(data):
        return unpack(data, **limits)[0]
    check_tile_count(data, max_work)
    grid, tiles = read(data, **limits)
    headers = [tile()[0] for tile in tiles]
    return replace(
        headers[0],
        height=grid.height,
        width=grid.width,
        restoration=max(h.restoration for h in headers),
    )


def check_region(region, height: int, width: int) -> tuple[int, int, int, int]:
    """``region`` (``row, column, height, width``; None: the whole image) checked against an image
    of ``height`` x ``width``; ``ValueError`` if it is not a non-empty box inside it."""
    if region is None:
        return 0, 0, height, width
    try:
        top, left, rows, cols = (int(v) for v in region)
    except (TypeError, ValueError):
        raise ValueError(f"region must be (row, column, height, width), got {region!r}") from None
    if not (
        0 <= top and 0 <= left and rows > 0 and cols > 0 and top + rows <= height and left + cols <= width
    ):
        raise ValueError(f"region {region!r} is not a box inside the {width} x {height} image")
    return top, left, rows, cols


def check_tile_count(data: bytes, max_work: int) -> None:
    """:class:`FormatError` if the tiles of ``data`` are more than ``max_work`` allows (:data:`TILE_WORK`),
    from the container's head alone: a 34 MB file may hold 262,144 tiles."""
    count = _tile_count(data)
    if count * TILE_WORK > max_work:
        raise FormatError(
            f"decoding these {count} tiles is {count * TILE_WORK:.3g} units of work, above the limit of "
            f"{max_work:.3g} (max_work)"
        )


def _tile_count(data: bytes) -> int:
    """The tiles of a tiled file by the sizes of its head (``len(cuts(...))`` by arithmetic, no list
    of boxes); 0 when the head is too short or out of range (:func:`read` says what is wrong)."""
    if len(data) < _HEAD.size:
        return 0
    _, _, _, height, width, tile = _HEAD.unpack_from(data)
    if not (height and width and tile >= MIN_TILE):
        return 0

    def along(size: int) -> int:
        n = -(-size // tile)
        return n - 1 if n > 1 and size - (n - 1) * tile < tile // 4 else n

    return along(height) * along(width)
