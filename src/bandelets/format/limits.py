"""Estimated working sets and work of the encoder and the decoder, and the limits a decoder enforces.

A few bytes of range-coded zeros can legitimately describe a huge image, so the size of a .bdl
file says nothing about the work it asks for: the decoder estimates it from the header
(:func:`check_memory`, :func:`check_work`) and refuses what exceeds ``max_memory`` or
``max_work``; the encoder likewise refuses an image before any work on it
(:func:`check_encodable`), and one whose file the default decoder would refuse.

An image coded in tiles (:mod:`bandelets.codec.tiles`) needs the working set of the tiles in flight
(:data:`~bandelets.codec.tiles.WORKERS`, each estimated as an image of its own) plus what the whole
image holds: the encoder 8 bytes per pixel (the file, a normal map's angular errors), the decoder
its float64 output. Measured peak RSS of a 2048 x 2048 x 3 map at 1 bpp in tiles of 512 (imports
and the map included, ``benchmarks/speed.py --memory``): 586 MiB to encode, 665 MiB to decode,
against estimates of 336 and 276 MiB of allocations (RSS adds the interpreter, numba's kernels and
the source map, about 250 MiB).
"""

from __future__ import annotations

from .container import TILE, WORKERS, Grid, cuts
from .fields import MAX_LEVELS, MAX_MEMORY, MAX_SAMPLES, MAX_SIDE, MAX_WORK, FormatError, padded_shape
from .header import Header

__all__ = [
    "OWN_FILE",
    "MAX_MEMORY",
    "MAX_WORK",
    "check_encodable",
    "check_memory",
    "check_work",
    "decoder_memory",
    "encoder_memory",
    "restoration_work",
    "tile_side",
]

#: The size limits of a file the encoder has just written itself (``unpack(data, **OWN_FILE)``): only
#: the caller's memory limit applies to it, not the limits on foreign files
#: (:data:`~bandelets.format.header.MAX_SIDE`, :data:`~bandelets.format.header.MAX_SAMPLES`).
OWN_FILE = {"max_side": 2**32, "max_samples": 2**64}

# Working set per padded pixel and per padded sample, measured with tracemalloc (peak of the
# numpy allocations, JIT compiled beforehand) on generated normal maps and their first channel:
# decode 512 x 512 x 1 and 1024 x 1024 x 1 and 2048 x 2048 x 1 peak at 72 B/sample,
# 512 x 512 x 3 and 1024 x 1024 x 3 at 42 B/sample, i.e. about 45 B/pixel + 27 B/sample;
# the estimate rounds up. Encoding at a fixed threshold peaks at 164 MiB for 512 x 512 x 1,
# 387 MiB for 2048 x 2048 x 1 (about 150 MiB of tables, the reorderings of every direction up
# to 32 x 32, plus 59 B/sample), 213 MiB for 1024 x 1024 x 3; a bpp target (rate control)
# peaks no higher than a fixed threshold (512 x 512 x 3, 170 MiB). The estimate rounds up.
# Since the encoder lets go of what it has used (the source during rate control, each pass's
# code lengths, the plain coefficients the directions are weighed against), a second encode
# (tables already made) of the crease normal map peaks at 152 MiB for 1024 x 1024 x 3 at 1 bpp
# (256 before), 580 MiB for 2048 x 2048 x 3 (676 before; 1312 estimated, one piece), 282 MiB for
# 2048 x 2048 x 1 at a fixed threshold (346 before): the estimate is left as it was, an upper
# bound, so that the sizes coded in one piece stay those of before.
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
# The loop filter (bandelets.restore.loopfilter: two float64 copies of the image, at most 20 taps a sample)
# runs once the restoration's buffers are freed: the peak is unchanged (512 x 512 x 2 bumps at 1
# bpp: 20.4 MiB with and without it), and its work, a fixed bound per sample, needs no limit.
_ENCODE_FIXED, _ENCODE_PER_SAMPLE = 160 * 2**20, 96
# A tiled encode holds, besides the tiles in flight, the angular error of every pixel of a
# normal map (float32, for its quality targets and the summary) and the file.
_TILED_ENCODE_PER_PIXEL = 8
# The fixed cost of a restoration iteration, in samples: the Python around the transforms
# (32 x 32 x 3 with local frames restores at 15 to 25 ms an iteration, 512 x 512 x 2 at
# 300 to 400 ns a sample, in one run on the 2-core machine).
_ITERATION_SAMPLES = 2**16


def decoder_memory(
    height: int,
    width: int,
    channels: int,
    levels: int,
    frames: bool = False,
    restoration: bool = False,
    tile: int = 0,
) -> int:
    """Estimated peak bytes the decoder allocates for an image of this size (``frames``: local
    frames; ``restoration``: restoration iterations), coded in tiles of side ``tile`` (0: in one
    piece; :func:`bandelets.codec.tiles.decode` estimates a file from its tiles' headers)."""
    if tile and Grid(height, width, tile).tiled:
        rows, cols = (max(s.stop - s.start for s in cuts(n, tile)) for n in (height, width))
        in_flight = WORKERS * decoder_memory(rows, cols, channels, levels, frames, restoration)
        return in_flight + 8 * height * width * channels
    rows, cols = padded_shape((height, width), levels)
    extra = _DECODE_FRAMES_PER_PIXEL if frames else 0
    per_sample = _DECODE_PER_SAMPLE + (_DECODE_RESTORATION_PER_SAMPLE if restoration else 0)
    return rows * cols * (_DECODE_PER_PIXEL + extra + per_sample * channels)


def encoder_memory(height: int, width: int, channels: int, tile: int = 0) -> int:
    """Estimated peak bytes the encoder allocates for an image of this size, coded in tiles of
    side ``tile`` (:mod:`bandelets.codec.tiles`; 0: in one piece)."""
    if not (tile and Grid(height, width, tile).tiled):
        rows, cols = padded_shape((height, width), MAX_LEVELS)
        return _ENCODE_FIXED + rows * cols * channels * _ENCODE_PER_SAMPLE
    rows, cols = (max(s.stop - s.start for s in cuts(n, tile)) for n in (height, width))
    in_flight = WORKERS * (encoder_memory(rows, cols, channels) - _ENCODE_FIXED)
    return _ENCODE_FIXED + in_flight + height * width * _TILED_ENCODE_PER_PIXEL


def tile_side(height: int, width: int, channels: int, tile: int = 0, max_memory: int = MAX_MEMORY) -> int:
    """The tile side :func:`bandelets.encode` codes an image with (0: one piece): ``tile`` when
    given, else (``tile=0``, the default) one piece while that needs no more than ``max_memory``
    (:func:`encoder_memory`), and tiles of :data:`~bandelets.codec.tiles.TILE` above.

    Why not always tiles: nothing crosses a tile border, and at low rates the borders of smooth
    maps show (``python benchmarks/tiling_cost.py --size 1024 --rates 0.25,1``: bumps -3.17 dB
    at 0.25 bpp in tiles of 512): tiles are for the sizes that would not fit otherwise.
    """
    if tile:
        return tile
    return 0 if encoder_memory(height, width, channels) <= max_memory else TILE


def check_encodable(
    height: int, width: int, channels: int, max_memory: int = MAX_MEMORY, tile: int | None = None
) -> None:
    """Raise ``ValueError`` for an image the encoder refuses before any work on it: one whose
    encoding in tiles of ``tile`` (0: in one piece; None: the side :func:`tile_side` chooses by
    default) needs more than ``max_memory`` bytes (:func:`encoder_memory`), or whose file the
    default decoder would refuse (a side above :data:`~bandelets.format.header.MAX_SIDE`, more samples
    than :data:`~bandelets.format.header.MAX_SAMPLES`)."""
    if tile is None:
        tile = tile_side(height, width, channels, 0, max_memory)
    need = encoder_memory(height, width, channels, tile)
    if need > max_memory:
        raise ValueError(
            f"encoding a {width} x {height} x {channels} image needs about "
            f"{need / 2**20:.0f} MiB, above the limit of {max_memory / 2**20:.0f} MiB "
            "(--max-memory, max_memory)"
        )
    if max(height, width) > MAX_SIDE or height * width * channels > MAX_SAMPLES:
        raise ValueError(
            f"a {width} x {height} x {channels} image exceeds what decoders accept by default "
            f"({MAX_SIDE} pixels per side, {MAX_SAMPLES} samples)"
        )


def check_memory(header: Header, max_memory: int = MAX_MEMORY) -> None:
    """Raise :class:`FormatError` if decoding ``header`` needs more than ``max_memory`` bytes.

    Also refuses more wavelet levels than the image has octaves: that is pure padding (the
    encoder never writes it), and the first use of a deep level costs seconds (the synthesis
    norms of :mod:`bandelets.transform.wavelets`).
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
            f"{need / 2**20:.0f} MiB, above the limit of {max_memory / 2**20:.0f} MiB "
            "(--max-memory, max_memory)"
        )


def restoration_work(header: Header) -> int:
    """The restoration work ``header`` asks for: iterations times the padded samples, plus
    65,536 (the fixed cost of an iteration)."""
    rows, cols = padded_shape((header.height, header.width), header.levels)
    return (rows * cols * header.channels + _ITERATION_SAMPLES) * header.restoration


def check_work(header: Header, max_work: int = MAX_WORK) -> None:
    """Raise :class:`~bandelets.format.header.FormatError` if ``header`` asks for more restoration work
    than ``max_work`` (:func:`restoration_work`): the decoding time, unlike the file size, grows
    with it."""
    work = restoration_work(header)
    if work > max_work:
        raise FormatError(
            f"restoring this {header.width} x {header.height} x {header.channels} image for "
            f"{header.restoration} iterations is {work:.3g} sample-iterations of work, above the limit of "
            f"{max_work:.3g} (max_work)"
        )
