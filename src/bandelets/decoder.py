"""Decoding of .bdl files: parse, entropy-decode, dequantize, restore, invert the transform, filter.

The encoder chooses the number of restoration iterations with :func:`restorations` and
:func:`decoded_image`, so that it measures exactly what the decoder returns.
"""

from __future__ import annotations

from dataclasses import replace
from itertools import islice

import numpy as np

from . import directional, entropy, frames, loopfilter, lossless, metrics, restoration, riesz, tiling
from .bandeletize import bandeletize, debandeletize
from .bitstream import LOSSLESS, MAX_MEMORY, MAX_WORK, FormatError, Header, unpack
from .blasthreads import one_blas_thread
from .coding import code_image, code_lifting, new_coders
from .memory import check_memory, check_work
from .quantize import dequantize
from .transform import apply_trees
from .wavelets import padded_shape, wavedec, waverec

__all__ = [
    "decode",
    "decode_parsed",
    "decoded_bins",
    "restorations",
    "channel_transforms",
    "decoded_image",
]


@one_blas_thread()  # the decoder runs threads of its own: BLAS one (bandelets.blasthreads)
def decode(
    data: bytes,
    *,
    restore: bool = True,
    max_memory: int = MAX_MEMORY,
    max_work: int = MAX_WORK,
    region: tuple[int, int, int, int] | None = None,
    progress: bool = False,
    **limits,
) -> np.ndarray:
    """Decode a .bdl file.

    Parameters
    ----------
    data : bytes
        The whole file.
    restore : bool
        Run the restoration iterations and the loop filter the file asks for
        (:mod:`bandelets.restoration`, :mod:`bandelets.loopfilter`).
        False: plain dequantization, a faster decode of lower quality (a preview).
    max_memory : int
        Refuse a file whose decoding needs more than this many bytes (estimated from its
        header, see :func:`bandelets.memory.check_memory`; default 2 GiB).
    max_work : int
        Refuse a file asking for more restoration work than this, iterations times padded
        samples (:func:`bandelets.memory.restoration_work`): the default, 2**28, is at most
        about 20 s of CPU time (``benchmarks/worst_decode.py``); for a tiled file, of each tile
        (:mod:`bandelets.tiling`: the time then grows with the tile count, as the image size).
    region : (row, column, height, width), optional
        Decode only this box of the image: of a tiled file, only the tiles it touches.
    progress : bool
        A progress bar on stderr over the tiles of a tiled file.
    **limits
        ``max_side`` and ``max_samples`` (see :func:`bandelets.bitstream.unpack`).

    Returns
    -------
    ndarray, float64, shape (H, W) for one channel or (H, W, C); a normal map's vectors are
    renormalised to unit length, but for a lossless file (:mod:`bandelets.lossless`): the
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
    if tiling.is_tiled(data):
        return tiling.decode(
            data,
            restore=restore,
            max_memory=max_memory,
            max_work=max_work,
            region=region,
            progress=progress,
            **limits,
        )
    header, streams = unpack(data, **limits)
    top, left, rows, cols = tiling.check_region(region, header.height, header.width)
    image = decode_parsed(header, streams, restore=restore, max_memory=max_memory, max_work=max_work)
    return image[top : top + rows, left : left + cols] if region is not None else image


def decode_parsed(
    header: Header,
    streams: tuple[bytes, bytes, bytes],
    *,
    restore: bool = True,
    max_memory: int = MAX_MEMORY,
    max_work: int = MAX_WORK,
) -> np.ndarray:
    """Decode a file already split by :func:`bandelets.bitstream.unpack` (options of :func:`decode`)."""
    if header.transform == LOSSLESS:
        check_memory(header, max_memory)
        try:
            return lossless.decode_file(header, streams[2])
        except entropy.CorruptStream as err:
            raise FormatError(f"corrupt .bdl file: {err}") from None
    if not restore:
        header = replace(header, restoration=0, loop_filter=None)
    check_memory(header, max_memory)
    check_work(header, max_work)
    trees, quantized, lifting = decoded_bins(header, streams)
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
    coders = new_coders(streams)
    try:
        trees, quantized, _ = code_image(coders, header)
        lifting = code_lifting(coders[1], header)
        for coder in coders:
            coder.check()
    except entropy.CorruptStream as err:
        raise FormatError(f"corrupt .bdl file: {err}") from None
    shape = padded_shape((header.height, header.width), header.levels)
    return trees, [q.reshape(shape) for q in quantized], lifting


def restorations(header: Header, trees: list, quantized: list[np.ndarray], lifting: list | None = None):
    """The channels after 0, 1, 2, ... restoration iterations (:func:`bandelets.restoration.iterate`)."""
    unit = header.kind == "normal-map" and header.channels == 3
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
    threads (:func:`bandelets.restoration.workers`, not new threads at every decode)."""
    if header.channels < 2 or header.height * header.width < THREADS_FROM or restoration.CORES < 2:
        return lambda function, channels: [function(channel) for channel in channels]

    def each(function, channels):
        first, *others = channels
        futures = [restoration.workers().submit(function, channel) for channel in others]
        return [function(first), *(future.result() for future in futures)]

    return each


def channel_transforms(header: Header, trees: list, quantized: list[np.ndarray], lifting: list | None = None):
    """The file's transform of the (padded) channels, ``(C, H, W)`` to ``(C, H, W)``, and its
    inverse (both overwrite their argument). With local frames, those of every level are the
    ones the decoder finds from the dequantized bins ``quantized``
    (:func:`bandelets.frames.to_global`), fixed from then on; ``lifting``: the directions of the
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
    if header.kind == "normal-map":  # 2 or 3 channels (bandelets.bitstream.unpack)
        # Two channels of a map of unit vectors are equidistant coordinates (bandelets.normalmaps).
        out = metrics.unit_normals(channels, header.height, header.width, equidistant=header.layout == "xyz")
        if out is None:
            raise overflow
        # Returned in the layout the source had (bandelets.bitstream.LAYOUTS).
        return out[..., :2] if header.layout == "xy" else out
    out = np.stack([c[: header.height, : header.width] for c in channels], axis=-1, dtype=np.float64)
    if not np.all(np.isfinite(out)):
        raise overflow
    return out[..., 0] if header.channels == 1 else out
