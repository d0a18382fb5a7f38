"""Decoding of .bdl files: parse, entropy-decode, dequantize, restore, invert the transform, filter.

The encoder chooses the number of restoration iterations with :func:`restorations` and
:func:`decoded_image`, so that it measures exactly what the decoder returns.
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from itertools import islice

import numpy as np

from ..coding import lossless, rangecoder
from ..coding.image import code_image, new_coders
from ..format.container import TILE_WORK, WORKERS, check_region, check_tile_count, is_tiled, output_of, read
from ..format.fields import (
    FORMAT_VERSION,
    LOSSLESS,
    MAGIC,
    MAX_MEMORY,
    MAX_WORK,
    FormatError,
    Kind,
    Layout,
    padded_shape,
)
from ..format.header import Header, unpack
from ..format.levels import parts
from ..format.limits import check_memory, check_work, decoder_memory, restoration_work
from ..format.quantizer import dequantize
from ..restore import loopfilter, restoration
from ..restore.precisions import compile_both
from ..runtime.blas import one_blas_thread
from ..runtime.progress import Progress
from ..runtime.threads import each, thread_map
from ..transform import directional, frames, riesz
from ..transform.bandeletize import bandeletize, debandeletize
from ..transform.bandelets import apply_trees
from ..transform.normals import unit_normals
from ..transform.wavelets import wavedec, waverec
from .levels import decode_level

__all__ = [
    "check",
    "decode",
    "decode_parsed",
    "decoded_bins",
    "decoded_from_bins",
    "restorations",
    "channel_transforms",
    "decoded_image",
]


@one_blas_thread()  # the decoder runs threads of its own: BLAS one (bandelets.runtime.blas)
def decode(
    data: bytes,
    *,
    restore: bool = True,
    max_memory: int = MAX_MEMORY,
    max_work: int = MAX_WORK,
    region: tuple[int, int, int, int] | None = None,
    progress: bool = False,
    level: int = 0,
    **limits,
) -> np.ndarray:
    """Decode a .bdl file.

    Parameters
    ----------
    data : bytes
        The whole file.
    restore : bool
        Run the restoration iterations and the loop filter the file asks for
        (:mod:`bandelets.restore.restoration`, :mod:`bandelets.restore.loopfilter`).
        False: plain dequantization, a faster decode of lower quality (a preview).
    max_memory : int
        Refuse a file whose decoding needs more than this many bytes (estimated from its
        header, see :func:`bandelets.format.limits.check_memory`; default 2 GiB).
    max_work : int
        Refuse a file asking for more restoration work than this, iterations times padded
        samples (:func:`bandelets.format.limits.restoration_work`): the default, 2**28, is at most
        about 20 s of CPU time (``benchmarks/worst_decode.py``); for a tiled file, of each tile
        (:mod:`bandelets.codec.tiles`: the time then grows with the tile count, as the image size).
    region : (row, column, height, width), optional
        Decode only this box of the image: of a tiled file, only the tiles it touches.
    progress : bool
        A progress bar on stderr over the tiles of a tiled file.
    level : int
        Decode the image at ``1 / 2**level`` of the size (each side rounded up) from the first bytes
        of the file only (format version 19; ``data`` may be a prefix of the file that holds that
        level, :func:`bandelets.codec.levels.level_bytes`): the wavelet transform's coarse
        approximation, without restoration (but a ``box_mips`` file's, with ``restore``) or loop
        filter (:mod:`bandelets.codec.levels`).
        0: the full decode. Not with ``region``; not of a lossless file.
    **limits
        ``max_side`` and ``max_samples`` (see :func:`bandelets.format.header.unpack`).

    Returns
    -------
    ndarray, float64, shape (H, W) for one channel or (H, W, C); a normal map's vectors are
    renormalised to unit length, but for a lossless file (:mod:`bandelets.coding.lossless`): the
    source's values exactly, every channel it stored.

    Raises
    ------
    FormatError
        For any corrupt, truncated or unsupported file, or one above the limits.
    TypeError
        When ``data`` is not bytes (or another buffer).

    Examples
    --------
    >>> import numpy as np
    >>> from bandelets import encode
    >>> image = np.linspace(0.0, 1.0, 32 * 48).reshape(32, 48)
    >>> decoded = decode(encode(image, threshold=0.01))
    >>> decoded.shape, bool(np.abs(decoded - image).max() < 0.05)
    ((32, 48), True)
    """
    try:
        data = bytes(memoryview(data))
    except TypeError:
        raise TypeError(f"decode takes the bytes of a .bdl file, not {type(data).__name__}") from None
    if level:
        if region is not None:
            raise ValueError("decode at a level takes no region: crop the image it returns")
        return decode_level(data, level, max_memory, restore=restore, max_work=max_work, **limits)
    if is_tiled(data):
        return _decode_tiles(
            data,
            restore=restore,
            max_memory=max_memory,
            max_work=max_work,
            region=region,
            progress=progress,
            **limits,
        )
    header, streams = unpack(data, **limits)
    top, left, rows, cols = check_region(region, header.height, header.width)
    image = decode_parsed(header, streams, restore=restore, max_memory=max_memory, max_work=max_work)
    return image[top : top + rows, left : left + cols] if region is not None else image


def check(data: bytes) -> bool:
    """Whether ``data`` starts like a .bdl file this decoder reads (its magic and format version), as
    imagecodecs' ``*_check`` functions say whether bytes are of their codec: nothing is decoded, so
    a file that checks may still be refused by :func:`decode`.

    Examples
    --------
    >>> import numpy as np
    >>> from bandelets import encode
    >>> check(encode(np.zeros((8, 8)), threshold=0.1)), check(b"\\x89PNG\\r\\n")
    (True, False)
    """
    head = bytes(memoryview(data)[:5])
    return len(head) == 5 and head[:4] == MAGIC and head[4] == FORMAT_VERSION


def decode_parsed(
    header: Header,
    streams: tuple[bytes, bytes, bytes],
    *,
    restore: bool = True,
    max_memory: int = MAX_MEMORY,
    max_work: int = MAX_WORK,
) -> np.ndarray:
    """Decode a file already split by :func:`bandelets.format.header.unpack` (options of :func:`decode`)."""
    if header.transform == LOSSLESS:
        check_memory(header, max_memory)
        try:
            return lossless.decode_file(header, streams[2])
        except rangecoder.CorruptStream as err:
            raise FormatError(f"corrupt .bdl file: {err}") from None
    if not restore:
        header = replace(header, restoration=0, loop_filter=None)
    check_memory(header, max_memory)
    check_work(header, max_work)
    return decoded_from_bins(header, *decoded_bins(header, streams))


def decoded_from_bins(
    header: Header, trees: list, quantized: list[np.ndarray], lifting: list | None
) -> np.ndarray:
    """The image of the quadtrees, bins and directions a file holds (:func:`decoded_bins`), restored
    and filtered as its ``header`` says: the decoder after the range decoding, which an encoder that
    has the bins it coded skips."""
    channels = next(islice(restorations(header, trees, quantized, lifting), header.restoration, None))
    if header.loop_filter is not None:
        channels = loopfilter.apply(
            channels, header.loop_filter, header.threshold, header.height, header.width, header.folded
        )
    return decoded_image(channels, header)


def decoded_bins(
    header: Header, streams: tuple[bytes, bytes, bytes]
) -> tuple[list, list[np.ndarray], list | None]:
    """The quadtrees, the bin indices, shape (H', W') per channel, and the directions of the
    levels lifted along directions (None without), that the streams hold."""
    coders = new_coders(parts(streams, header.segments))
    try:
        lifting: list = []
        trees, quantized, _ = code_image(coders, header, lifting=lifting)
        lifting = lifting if header.lifting else None
    except rangecoder.CorruptStream as err:
        raise FormatError(f"corrupt .bdl file: {err}") from None
    shape = padded_shape((header.height, header.width), header.levels)
    return trees, [q.reshape(shape) for q in quantized], lifting


def restorations(header: Header, trees: list, quantized: list[np.ndarray], lifting: list | None = None):
    """The channels after 0, 1, 2, ... restoration iterations
    (:func:`bandelets.restore.restoration.iterate`)."""
    unit = header.kind == Kind.NORMAL_MAP and header.channels == 3
    compile_both()  # the file chooses a precision: both compiled at once (issue 40)
    return restoration.iterate(
        quantized,
        header.threshold,
        *channel_transforms(header, trees, quantized, lifting),
        unit_vectors=(header.height, header.width) if unit else None,
        folded=header.folded or header.extension == "spherical",
        second_across=header.folded,
    )


#: Pixels from which the restoration transforms the channels in parallel threads (independent
#: transforms; numpy lets go of the GIL on large arrays): a two-channel crease map decodes
#: 1.3 times faster at 2048 x 2048 and 1024 x 1024, 1.1 times at 512 x 512, but 1.4 times slower
#: at 256 x 256, where the threads mostly wait for each other (``benchmarks/speed.py``).
THREADS_FROM = 512 * 512


def _channel_map(header: Header):
    """``each(function, channels)``, the list of ``function(channel)``: from :data:`THREADS_FROM`
    pixels on, the first channel in the calling thread and the others in the process's worker
    threads (:func:`bandelets.runtime.threads.each`)."""
    return partial(each, threaded=header.height * header.width >= THREADS_FROM)


def channel_transforms(header: Header, trees: list, quantized: list[np.ndarray], lifting: list | None = None):
    """The file's transform of the (padded) channels, ``(C, H, W)`` to ``(C, H, W)``, and its
    inverse (both overwrite their argument). With local frames, those of every level are the
    ones the decoder finds from the dequantized bins ``quantized``
    (:func:`bandelets.transform.frames.to_global`), fixed from then on; ``lifting``: the directions of the
    levels lifted along directions, if any."""
    t1d, levels, args = header.transform_1d, header.levels, (header.wavelet, header.levels, header.extension)
    each = _channel_map(header)
    level_frames = None
    if header.frames:
        decoded = [
            apply_trees(dequantize(q, header.threshold), levels, trees, debandeletize, t1d) for q in quantized
        ]
        level_frames = frames.to_global(decoded, *args, header.normal_weight, header.kind)

    # In place, channel by channel: no copy of the image.
    sign, precision = header.riesz, riesz.precision(header.threshold)

    def analysis(x: np.ndarray) -> np.ndarray:  # overwrites x
        c = x
        if sign:  # the channels' Riesz pair is what the wavelets code
            x[0], x[1] = riesz.forward(*(x[k].astype(precision, copy=False) for k in (0, 1)), sign)
        if lifting is not None:
            each(lambda k: directional.transform(x[k], levels, header.lifting, lifting), range(len(c)))
        else:
            each(lambda k: wavedec(x[k], *args, out=x[k]), range(len(c)))
        if level_frames is not None:
            frames.rotate_levels(list(c), level_frames, levels, header.normal_weight, local=True)
        each(lambda k: apply_trees(c[k], levels, trees, bandeletize, t1d, inplace=True), range(len(c)))
        return c

    def synthesis(c: np.ndarray) -> np.ndarray:  # overwrites c
        each(lambda k: apply_trees(c[k], levels, trees, debandeletize, t1d, inplace=True), range(len(c)))
        if level_frames is not None:
            frames.rotate_levels(list(c), level_frames, levels, header.normal_weight, local=False)
        if lifting is not None:
            each(
                lambda k: directional.transform(c[k], levels, header.lifting, lifting, inverse=True),
                range(len(c)),
            )
        else:
            each(lambda k: waverec(c[k], *args, out=c[k]), range(len(c)))
        if sign:
            c[0], c[1] = riesz.inverse(*(c[k].astype(precision, copy=False) for k in (0, 1)), sign)
        return c

    return analysis, synthesis


def decoded_image(channels, header: Header) -> np.ndarray:
    """What :func:`decode` returns, from the decoded (padded) channels."""
    overflow = FormatError("corrupt .bdl file: the decoded values overflow")
    if header.kind == Kind.NORMAL_MAP:  # 2 or 3 channels (bandelets.format.header.unpack)
        # Two channels of a map of unit vectors are equidistant coordinates (bandelets.codec.normalmaps).
        out = unit_normals(channels, header.height, header.width, equidistant=header.layout == Layout.XYZ)
        if out is None:
            raise overflow
        # Returned in the layout the source had (bandelets.format.header.LAYOUTS).
        return out[..., :2] if header.layout == Layout.XY else out
    out = np.stack([c[: header.height, : header.width] for c in channels], axis=-1, dtype=np.float64)
    if not np.all(np.isfinite(out)):
        raise overflow
    return out[..., 0] if header.channels == 1 else out


def _decode_tiles(
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
    of the tiles decoded, all together (:func:`bandelets.format.limits.restoration_work`), as it bounds
    that of an image in one piece, plus :data:`~bandelets.format.container.TILE_WORK` for each tile.
    """

    check_tile_count(data, max_work)  # from the head alone: a 34 MB file may hold 262,144 tiles
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
    channels = output_of(headers[0])[3]
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
        for (r, c), tile in thread_map(decoded, parsed, WORKERS):
            tile = tile.reshape(tile.shape[:2] + (channels,))
            r_in = slice(max(r.start, top), min(r.stop, top + rows))
            c_in = slice(max(c.start, left), min(c.stop, left + cols))
            out[_shift(r_in, top), _shift(c_in, left)] = tile[_shift(r_in, r.start), _shift(c_in, c.start)]
            line.step()
    return out[..., 0] if channels == 1 else out


def _shift(span: slice, by: int) -> slice:
    return slice(span.start - by, span.stop - by)
