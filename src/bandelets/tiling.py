"""Large images coded as independent tiles (format version 9): bounded memory, flat time per
pixel, both cores, and a decoder that can read a region.

An image with a side above the tile side (:data:`TILE`, 512 by default) is cut into a grid of
tiles, each coded as a complete .bdl file (its own quadtrees, bins and restoration, see
:mod:`bandelets.encoder`), and the tiles are stored one after the other in a container::

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
per sample, :mod:`bandelets.memory`), the restoration's iterations and the basis search grow
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

Written here: the container is ours, and the thread pool is the standard library's.
"""

from __future__ import annotations

import struct
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from .bitstream import (
    FORMAT_VERSION,
    MAGIC,
    MAX_SAMPLES,
    MAX_SIDE,
    MAX_WORK,
    TILED_CODE,
    FormatError,
    Header,
    unpack,
)

__all__ = [
    "TILE",
    "MIN_TILE",
    "TILE_WORK",
    "WORKERS",
    "Grid",
    "cuts",
    "is_tiled",
    "read",
    "pack",
    "header_of",
]

#: Default tile side: a 512 x 512 map is one tile, coded as before.
TILE = 512
#: Smallest tile side a file may have (the tests use small tiles).
MIN_TILE = 16
#: Tiles coded or decoded at once (threads): the machine's two cores.
WORKERS = 2
#: The fixed work of decoding a tile, in the units of ``max_work`` (sample-iterations of
#: restoration, :func:`bandelets.memory.restoration_work`), counted for every tile a decode reads
#: (issue 40): a tile costs its parsing, its range decoders and its transforms' set-up whatever its
#: size, 0.8 to 1.4 ms of CPU, so that 4,096 tiles of 16 x 16 without restoration (a 537 KB file)
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
    ``i`` (:func:`bandelets.bitstream.unpack`) and checks it against the grid and the first tile.

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
            if _output(header) != _output(first[0]):
                raise FormatError(f"corrupt .bdl file: tile {i} is not of the kind of the first tile")
            return header, streams

        return parse

    return grid, [tile_reader(i) for i in range(len(boxes))]


def _output(header: Header) -> tuple:
    """What a tile's decoded array is made of, which every tile of a file shares."""
    channels = 3 if header.kind == "normal-map" and header.layout != "xy" else header.channels
    return header.kind, header.layout, header.depth, channels


def header_of(data: bytes, max_work: int = MAX_WORK, **limits) -> Header:
    """The header of a .bdl file, tiled or not: for a tiled file, that of its first tile with the
    whole image's size and the most restoration iterations of any tile (refused, as by
    :func:`decode`, when its tiles are more than ``max_work`` allows: every tile is parsed)."""
    if not is_tiled(data):
        return unpack(data, **limits)[0]
    _check_tile_count(data, max_work)
    grid, tiles = read(data, **limits)
    headers = [tile()[0] for tile in tiles]
    return replace(
        headers[0],
        height=grid.height,
        width=grid.width,
        restoration=max(h.restoration for h in headers),
    )


def thread_map(function, items, workers: int = WORKERS):
    """``function`` over ``items`` in ``workers`` threads, results in order, at most ``workers``
    items in flight (the memory bound)."""
    if workers < 2:
        yield from map(function, items)
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        items = iter(items)
        pending = [pool.submit(function, item) for _, item in zip(range(workers), items, strict=False)]
        while pending:
            result = pending.pop(0).result()
            for item in items:
                pending.append(pool.submit(function, item))
                break
            yield result


def decode(
    data: bytes,
    *,
    restore: bool = True,
    max_memory: int,
    max_work: int,
    region: tuple[int, int, int, int] | None = None,
    progress: bool = False,
    **limits,
) -> np.ndarray:
    """Decode a tiled .bdl file (see :func:`bandelets.decode`), only the tiles ``region``
    (``row, column, height, width``) touches when given, at most :data:`WORKERS` tiles at once.

    ``max_memory`` bounds the output and the tiles in flight; ``max_work`` bounds the restoration
    of the tiles decoded, all together (:func:`bandelets.memory.restoration_work`), as it bounds
    that of an image in one piece, plus :data:`TILE_WORK` for each tile.
    """
    from .decoder import decode_parsed
    from .memory import decoder_memory, restoration_work
    from .progress import Progress

    _check_tile_count(data, max_work)  # from the head alone: a 34 MB file may hold 262,144 tiles
    grid, tiles = read(data, **limits)
    top, left, rows, cols = check_region(region, grid.height, grid.width)
    wanted = [
        (i, box)
        for i, box in enumerate(grid.boxes)
        if box[0].start < top + rows
        and top < box[0].stop
        and box[1].start < left + cols
        and left < box[1].stop
    ]
    fixed = len(wanted) * TILE_WORK
    parsed = [(box, tiles[i]()) for i, box in wanted]
    headers = [replace(h, restoration=0) if not restore else h for _, (h, _) in parsed]
    channels = _output(headers[0])[3]
    out_bytes = rows * cols * channels * 8
    per_tile = max(
        decoder_memory(h.height, h.width, h.channels, h.levels, h.frames, h.restoration > 0) for h in headers
    )
    work = sum(restoration_work(h) for h in headers) + fixed
    if work > max_work:
        raise FormatError(
            f"restoring these {len(headers)} tiles is {work:.3g} sample-iterations of work, above the limit "
            f"of {max_work:.3g} (max_work)"
        )
    need = out_bytes + min(WORKERS, len(parsed)) * per_tile
    if need > max_memory:
        raise FormatError(
            f"decoding this {cols} x {rows} x {channels} image needs about {need / 2**20:.0f} MiB, above the "
            f"limit of {max_memory / 2**20:.0f} MiB (--max-memory, max_memory)"
        )
    out = np.empty((rows, cols, channels))

    def decoded(item):
        box, (header, streams) = item
        return box, decode_parsed(header, streams, restore=restore, max_memory=per_tile, max_work=max_work)

    with Progress(progress) as line:
        line.stage(f"decoding {len(parsed)} tiles")
        for (r, c), tile in thread_map(decoded, parsed):
            tile = tile.reshape(tile.shape[:2] + (channels,))
            r_in = slice(max(r.start, top), min(r.stop, top + rows))
            c_in = slice(max(c.start, left), min(c.stop, left + cols))
            out[_shift(r_in, top), _shift(c_in, left)] = tile[_shift(r_in, r.start), _shift(c_in, c.start)]
            line.step()
    return out[..., 0] if channels == 1 else out


def _check_tile_count(data: bytes, max_work: int) -> None:
    """:class:`FormatError` if the tiles of ``data`` are more than ``max_work`` allows (:data:`TILE_WORK`)."""
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


def _shift(span: slice, by: int) -> slice:
    return slice(span.start - by, span.stop - by)


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


@dataclass
class _Tile:
    """One tile coded at a threshold, and what the encoder measured of it."""

    data: bytes
    coefficient_sse: float
    sse: float = 0.0  # squared error of the decoded tile as :func:`bandelets.metrics.psnr` counts it
    samples: int = 0
    extremes: np.ndarray | None = None  # (2, C): the least and the largest value of each channel
    angles: np.ndarray | None = None  # angular error of each pixel, degrees, float32 (normal maps)


def encode(array, options, *, bpp=None, threshold=None, psnr=None, max_angle=None, measured=False):
    """:func:`bandelets.encoder.encode_with_stats` for an image of more than one tile
    (:func:`side`): every tile coded at one threshold, found by one search on the whole file's
    size or quality, at most :data:`WORKERS` tiles in flight.

    The returned :class:`~bandelets.encoder.Encoded` holds the PSNR of the whole decoded image (and
    for a normal map its angular error) when ``measured``, but not the decoded image itself.
    """
    from . import metrics, ratecontrol
    from .bitstream import HEADER_BYTES, MAX_THRESHOLD, MIN_THRESHOLD
    from .encoder import Encoded, encode_with_stats
    from .files import as_read
    from .memory import check_encodable
    from .progress import Progress

    source = np.asarray(array)
    grid = Grid(source.shape[0], source.shape[1], side(source, options))
    check_encodable(
        grid.height, grid.width, source.shape[2] if source.ndim == 3 else 1, options.max_memory, grid.tile
    )
    fixed = len(grid.boxes) * TILE_WORK  # what the decoder counts for the tiles (TILE_WORK)
    if fixed > options.max_work:
        raise ValueError(
            f"{len(grid.boxes)} tiles of {grid.tile} are {fixed:.3g} units of work to decode, above the "
            f"limit of {options.max_work:.3g} (max_work): choose larger tiles"
        )
    kind = options.kind
    # No loop filter: its bytes would come after the search of the threshold of every tile.
    tile_options = replace(options, progress=False, tile=grid.tile, loop_filter=False)

    def coded(box, t: float, restore: bool, keep: bool, unrestored: _Tile | None) -> _Tile:
        tile = source[box]
        earlier = None if unrestored is None else Encoded(unrestored.data, t, unrestored.coefficient_sse)
        # Each tile's share of max_work, by its pixels: the restoration of the whole file is bounded
        # as that of one piece is (and as the decoder checks it), not max_work once per tile.
        share = (options.max_work - fixed) * tile.shape[0] * tile.shape[1] // (grid.height * grid.width)
        encoded = encode_with_stats(
            tile,
            replace(tile_options, restore=restore, max_work=share),
            threshold=t,
            measured=keep,
            unrestored=earlier,
        )
        out = _Tile(encoded.data, encoded.coefficient_sse)
        if keep:
            reference, depth = _reference(tile, options)
            decoded = np.asarray(as_read(encoded.decoded, kind, depth)).reshape(reference.shape)
            out.sse, out.samples, out.extremes = _squared_error(reference, decoded, kind)
            if kind == "normal-map":
                out.angles = metrics.angles(reference, decoded).astype(np.float32)
        return out

    with Progress(options.progress) as line:
        # The tiles of each pass without restoration (their bytes): the last pass restores and
        # measures those of its threshold rather than coding them again.
        passes: dict[float, list[_Tile]] = {}

        def encode_at(t: float, restore: bool, keep: bool) -> Encoded:
            line.stage(f"pass {len(passes) + 1}, T={t:.3g}: tiles", restart=True)
            t = max(t, MIN_THRESHOLD)
            earlier = passes.get(t) if restore or keep else None

            def one(item):
                box, unrestored = item
                return coded(box, t, restore, keep, unrestored)

            tiles = []
            for tile in thread_map(one, zip(grid.boxes, earlier or [None] * len(grid.boxes), strict=True)):
                tiles.append(tile)
                line.step()
            if not (restore or keep):
                passes[t] = [_Tile(tile.data, tile.coefficient_sse) for tile in tiles]
            data = pack(grid, [tile.data for tile in tiles])
            result = Encoded(data, t, sum(tile.coefficient_sse for tile in tiles))
            if not keep:
                return result
            sse, samples = sum(tile.sse for tile in tiles), sum(tile.samples for tile in tiles)
            top = metrics.peak(np.concatenate([tile.extremes for tile in tiles]), kind)
            result = replace(
                result, psnr=float("inf") if sse == 0 else 20.0 * np.log10(top / np.sqrt(sse / samples))
            )
            if kind == "normal-map":
                angles = np.concatenate([tile.angles for tile in tiles])
                result = replace(
                    result,
                    angles=metrics.AngularError(
                        float(angles.mean(dtype=np.float64)),
                        float(np.percentile(angles, 99)),
                        float(angles.max()),
                    ),
                )
            return result

        if threshold is not None:
            return encode_at(float(threshold), options.restore, measured)
        magnitudes, count, t_max, top = _coefficient_sample(source, grid, options)
        t_max = min(max(t_max, MIN_THRESHOLD), MAX_THRESHOLD)
        if bpp is not None:
            target = int(bpp * grid.height * grid.width / 8)
            if target < HEADER_BYTES:
                raise ValueError(f"target of {bpp:g} bpp ({target} bytes) cannot be reached")
            model = ratecontrol.size_model(magnitudes, count)
            best = ratecontrol.for_size(
                lambda t: encode_at(t, False, False), target, t_max, model, None, MIN_THRESHOLD
            )
            if options.restore or measured:  # the same tiles, restored and measured
                best = encode_at(best.threshold, options.restore, measured)
            return best
        if max_angle is not None:
            goal, t_guess = -20.0 * np.log10(max_angle), min(t_max, np.radians(max_angle))

            def quality(encoded) -> float:
                return -20.0 * np.log10(max(encoded.angles.p99, 1e-12))

            def label(q: float) -> str:
                return f"p99 angle of {10 ** (-q / 20):.3g} degrees"
        else:
            goal, t_guess = float(psnr), min(t_max, 2.0 * top * 10 ** (-psnr / 20)) or t_max / 1e3

            def quality(encoded) -> float:
                return encoded.psnr

            def label(q: float) -> str:
                return f"PSNR of {q:.2f} dB"

        return ratecontrol.for_quality(
            lambda t: encode_at(t, options.restore, True),
            quality,
            goal,
            t_max,
            t_guess,
            None,
            label,
            MIN_THRESHOLD,
        )


def _reference(tile: np.ndarray, options) -> tuple[np.ndarray, int]:
    """What the encoder measures a decoded tile against (as :func:`bandelets.encoder.encode_with_stats`
    does: a normal map as unit vectors, ``x, y`` alone for that layout), and the source's depth."""
    from . import metrics, normalmaps

    if options.kind != "normal-map":
        return np.asarray(tile, np.float64), options.depth
    x, depth, layout = normalmaps.prepare(tile, options.depth, options.xy)
    x = metrics.unit_vectors(np.asarray(x, np.float64))
    return (x[..., :2] if layout == "xy" else x), depth


def _compared(reference: np.ndarray, kind: str) -> np.ndarray:
    """``reference`` as :func:`bandelets.metrics.psnr_against` compares it."""
    from . import metrics

    if kind == "normal-map":
        return metrics.unit_vectors(metrics.with_z(reference) if reference.shape[-1] == 2 else reference)
    return reference


def _extremes(compared: np.ndarray) -> np.ndarray:
    """(2, C): the least and the largest value of each channel, from which
    :func:`bandelets.metrics.peak` of the whole image follows."""
    flat = compared.reshape(-1, compared.shape[-1] if compared.ndim == 3 else 1)
    return np.stack([flat.min(axis=0), flat.max(axis=0)])


def _squared_error(reference: np.ndarray, decoded: np.ndarray, kind: str) -> tuple[float, int, np.ndarray]:
    """Squared error of ``decoded`` summed as :func:`bandelets.metrics.psnr` sums it, the samples it
    is averaged over, and :func:`_extremes` of the reference."""
    from . import metrics

    compared = _compared(reference, kind)
    if kind == "normal-map" and reference.shape[-1] == 2:
        decoded = metrics.with_z(decoded)
    return (
        float(np.sum((compared - decoded.reshape(compared.shape)) ** 2)),
        compared.size,
        _extremes(compared),
    )


#: Coefficients the size model of rate control samples (:func:`bandelets.ratecontrol.size_model`).
_MODEL_SAMPLES = 2**20


def _coefficient_sample(source: np.ndarray, grid: Grid, options) -> tuple[np.ndarray, int, float, float]:
    """A regular sample of the magnitudes of the tiles' wavelet coefficients (the channels the
    encoder codes, before any local frames), their count, a threshold above all of them (the
    encoder's ``t_max``) and the peak of the whole image's PSNR."""
    from . import metrics
    from .transform import wavelet_coefficients
    from .wavelets import max_levels

    samples, count, largest, extremes = [], 0, 0.0, []
    step = max(1, source.size // _MODEL_SAMPLES) | 1
    for box in grid.boxes:
        reference, _ = _reference(source[box], options)
        compared = _compared(reference, options.kind)
        extremes.append(_extremes(compared))
        channels = compared if compared.ndim == 3 else compared[..., None]
        if options.kind == "normal-map" and np.all(channels[..., 2] >= 0):
            channels = channels[..., :2]
        coefficients = wavelet_coefficients(
            channels, options.wavelet, max_levels(channels.shape[:2]), options.extension
        )
        magnitudes = np.abs(np.concatenate([c.ravel() for c in coefficients]))
        samples.append(magnitudes[::step].copy())  # a view would hold every tile's coefficients
        count += magnitudes.size
        largest = max(largest, float(magnitudes.max()))
    weight = options.normal_weight if options.frames else 1.0
    top = metrics.peak(np.concatenate(extremes), options.kind)
    return np.concatenate(samples), count, 2.0 * largest * max(1.0, weight), top


def side(array, options) -> int:
    """The tile side :func:`bandelets.encode` codes ``array`` with (0: one piece; see ``tile``
    there and :func:`bandelets.memory.tile_side`): one piece for the spherical extension (a
    spherical geometry image folds its borders onto each other)."""
    from .memory import tile_side

    shape = np.shape(array)
    if len(shape) not in (2, 3) or options.extension != "symmetric":
        return 0
    return tile_side(*shape[:2], shape[2] if len(shape) == 3 else 1, options.tile, options.max_memory)


def tiled(array, options) -> bool:
    """Whether :func:`bandelets.encode` codes ``array`` in more than one tile (:func:`side`)."""
    tile = side(array, options)
    return bool(tile) and Grid(*np.shape(array)[:2], tile).tiled
