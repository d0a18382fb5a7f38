"""The bandelet codec: the transform of the paper end to end, and .bdl encode / decode.

``forward`` and ``inverse`` are the paper's bandelet transform of one channel (steps (1) to
(10)): pad, 2D wavelet transform, then in every detail subband the Lagrangian search of
the best direction of every dyadic square, the best quadtree, and the bandeletization.
``encode`` and ``decode`` add quantization (Q_T), entropy coding and the file format, for
images of one to four channels; rate control lives in :mod:`bandelets.ratecontrol`.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from itertools import islice

import numpy as np

from . import entropy, frames, metrics, ratecontrol, restoration
from .bandeletize import TRANSFORMS_1D, bandeletize, debandeletize, debandeletize_bins
from .bitstream import (
    HEADER_BYTES,
    KINDS,
    MAX_MEMORY,
    MAX_NORMAL_WEIGHT,
    MIN_NORMAL_WEIGHT,
    TRANSFORMS,
    FormatError,
    Header,
    check_memory,
    encoder_memory,
    implied_options,
    pack,
    unpack,
)
from .geometry import directions, nearest_direction
from .lagrangian import LAMBDA, best_directions
from .layout import approximation_plan, subband_plan
from .quadtree import MIN_WIDTH, best_quadtree, flat_quadtree, root_width
from .quantize import PROMOTE_ABOVE, RECONSTRUCTION, dequantize, quantize
from .treecoding import N_DIRECTION_CONTEXTS, N_SPLIT_CONTEXTS, code_tree, predicted_directions, reference_of
from .wavelets import WAVELETS, check_extension, max_levels, padded_shape, subband_slices, wavedec, waverec

__all__ = ["Bandelets", "forward", "inverse", "encode_at_threshold", "decode", "check_image"]


@dataclass(frozen=True)
class Bandelets:
    """Bandelet representation of one channel.

    Attributes
    ----------
    coefficients : ndarray, shape (H', W'), float64
        Wavelet coefficients (Mallat layout, padded size) with every bandelet square replaced
        by its 1D coefficients in zig-zag order.
    trees : list of Quadtree
        Segmentation and directions of each detail subband, coarsest level first, H, V, D.
    shape : (H, W)
        Size of the channel before padding.
    wavelet : str
    levels : int
    threshold : float
        The ``T`` the basis was chosen for.
    transform_1d : str
        The 1D transform along the directions.
    """

    coefficients: np.ndarray
    trees: list
    shape: tuple
    wavelet: str
    levels: int
    threshold: float
    transform_1d: str = "alpert2"


def _pad(channel: np.ndarray, levels: int) -> np.ndarray:
    rows, cols = padded_shape(channel.shape, levels)
    # Mirror padding keeps the padded image as smooth as the original at its border.
    return np.pad(channel, ((0, rows - channel.shape[0]), (0, cols - channel.shape[1])), mode="symmetric")


def _best_trees(
    coefficients: list[np.ndarray],
    levels: int,
    threshold: float,
    transform: str,
    transform_1d: str,
    before=None,
) -> list:
    """Best quadtree and directions of every detail subband (paper steps (3) to (8), (10)).

    ``coefficients`` holds the wavelet coefficients of every channel; they share one geometry.
    ``before(index, trees)``, if given, is called before subband ``index`` is read, with the
    trees of the coarser subbands (it may change the coefficients not read yet).
    """
    trees = []
    for index, (_, orientation, where) in enumerate(subband_slices(coefficients[0].shape, levels)):
        if before is not None:
            before(index, trees)
        subbands = np.stack([c[where] for c in coefficients])
        root = root_width(subbands.shape[1:])
        if transform == "wavelet" or root == 0:
            trees.append(flat_quadtree(subbands.shape[1:], root))
            continue
        covered = subbands[:, : subbands.shape[1] // root * root, : subbands.shape[2] // root * root]
        costs, dirs = [], []
        reference = reference_of(trees, index, orientation)
        width = MIN_WIDTH
        while width <= root:
            predicted = predicted_directions(
                reference, (covered.shape[1] // width, covered.shape[2] // width), width
            )
            hints = _children_directions(dirs[-1], width) if dirs else None
            cost, d = best_directions(
                covered, width, threshold, transform_1d=transform_1d, predicted=predicted, hints=hints
            )
            costs.append(cost)
            dirs.append(d)
            width *= 2
        trees.append(best_quadtree(costs, dirs, LAMBDA * threshold * threshold))
    return trees


def _children_directions(children: np.ndarray, width: int) -> np.ndarray:
    """The directions of the four half-size squares of every square of ``width``, as indices
    at ``width`` (-1 for NULL): where the search of the larger square starts."""
    rows, cols = children.shape[0] // 2, children.shape[1] // 2
    quads = children.reshape(rows, 2, cols, 2).transpose(0, 2, 1, 3).reshape(rows, cols, 4)
    out = np.full(quads.shape, -1, np.int64)
    some = quads >= 0
    out[some] = nearest_direction(directions(width // 2)[0][quads[some]], width)
    return out


def _apply_trees(
    coefficients: np.ndarray, levels: int, trees: list, transform_fn, transform_1d: str
) -> np.ndarray:
    out = coefficients.copy()
    for (_, _, where), tree in zip(subband_slices(coefficients.shape, levels), trees, strict=True):
        out[where] = transform_fn(coefficients[where], tree, transform_1d)
    return out


def forward(
    channel: np.ndarray,
    threshold: float,
    *,
    wavelet: str = "cdf97",
    levels: int | None = None,
    transform: str = "bandelet",
    transform_1d: str = "alpert2",
) -> Bandelets:
    """Bandelet transform of one channel, with the basis chosen for threshold ``T``.

    Parameters
    ----------
    channel : ndarray, shape (H, W)
        Finite values.
    threshold : float
        ``T`` > 0: the quantization step the Lagrangian optimises the basis for.
    wavelet : str
        ``"cdf97"`` (biorthogonal, default) or an orthogonal wavelet of
        :data:`bandelets.wavelets.WAVELETS`.
    levels : int, optional
        Wavelet levels (default :func:`bandelets.wavelets.max_levels`).
    transform : {"bandelet", "wavelet"}
        ``"wavelet"`` keeps every square NULL.
    transform_1d : {"alpert2", "haar"}
        1D transform along the directions (:data:`bandelets.bandeletize.TRANSFORMS_1D`):
        Alpert's multiwavelet with two vanishing moments (default) or the paper's Haar.

    Returns
    -------
    Bandelets
    """
    if np.ndim(channel) != 2:
        raise ValueError(f"forward takes one channel, an H x W array; got shape {np.shape(channel)}")
    x = check_image(channel, "image")[..., 0]
    _check_options(threshold, transform, wavelet, transform_1d)
    levels = levels or max_levels(x.shape)
    c = wavedec(_pad(x, levels), wavelet, levels)
    trees = _best_trees([c], levels, threshold, transform, transform_1d)
    return Bandelets(
        _apply_trees(c, levels, trees, bandeletize, transform_1d),
        trees,
        x.shape,
        wavelet,
        levels,
        threshold,
        transform_1d,
    )


def inverse(b: Bandelets) -> np.ndarray:
    """Inverse bandelet transform: the channel, shape ``b.shape``."""
    c = _apply_trees(b.coefficients, b.levels, b.trees, debandeletize, b.transform_1d)
    return waverec(c, b.wavelet, b.levels)[: b.shape[0], : b.shape[1]]


def _activity(known: list[np.ndarray], shape: tuple[int, int], levels: int, index: int):
    """Activity of the coarser subband under squares of detail subband ``index``.

    Returns ``(rows, cols, widths) -> bucket``: 0 if every already coded coefficient (all
    channels) of the parent region is 0, 1 if their magnitudes sum to at most 2, 2 above;
    3 for the coarsest detail level, whose parent is the approximation.
    """
    if index < 3:
        return lambda rows, cols, widths: np.full(np.broadcast(rows, cols, widths).shape, 3)
    where = subband_slices(shape, levels)[index - 3][2]
    magnitude = sum(np.abs(k.reshape(shape)[where]) for k in known)
    table = np.zeros((magnitude.shape[0] + 1, magnitude.shape[1] + 1), np.int64)
    table[1:, 1:] = magnitude.cumsum(0).cumsum(1)

    def bucket(rows, cols, widths):
        rows, cols, widths = np.broadcast_arrays(rows, cols, widths)
        r0, c0 = rows // 2, cols // 2
        r1 = np.minimum((rows + widths) // 2, magnitude.shape[0])
        c1 = np.minimum((cols + widths) // 2, magnitude.shape[1])
        total = table[r1, c1] - table[r0, c1] - table[r1, c0] + table[r0, c0]
        return np.where(total == 0, 0, np.where(total <= 2, 1, 2))

    return bucket


def code_image(
    coders: tuple, header: Header, trees: list | None = None, quantized: list[np.ndarray] | None = None
) -> tuple[list, list, list]:
    """Code (``trees`` and ``quantized`` given) or decode everything the streams hold.

    Order: the approximation of every channel, then subband by subband (coarse to fine,
    H, V, D): its quadtree and directions (:mod:`bandelets.treecoding`), then for each
    channel its bandelet squares and the rest of its coefficients (:mod:`bandelets.layout`).
    The guide of a channel (a context, see :func:`bandelets.entropy.code_coefficients`) is
    what the previous channel coded, bandelet coefficients included. After a channel's
    bandelet squares, the contexts are given the wavelet coefficients those
    squares decode to.

    Returns
    -------
    trees : list of Quadtree
    quantized : list of ndarray of int32, shape (H * W,), per channel
    spent : list of ndarray of float64, shape (H * W,): ideal code length of every coefficient
    """
    splits, dirs, coeffs = coders
    shape = padded_shape((header.height, header.width), header.levels)
    size = shape[0] * shape[1]
    decoding = quantized is None
    if decoding:
        quantized = [np.zeros(size, np.int32) for _ in range(header.channels)]
    known = [np.zeros(size, np.int64) for _ in quantized]
    spent = [np.zeros(size) for _ in quantized]
    approximation = approximation_plan(shape, header.levels)
    guides = [np.zeros(0, np.int32)] + quantized[:-1]
    for c, q in enumerate(quantized):
        entropy.code_coefficients(coeffs, q, approximation, known[c], guides[c], spent[c])
    out = []
    for index, (_, orientation, where) in enumerate(subband_slices(shape, header.levels)):
        band = (where[0].stop - where[0].start, where[1].stop - where[1].start)
        if header.transform == "bandelet":
            tree = code_tree(
                splits,
                dirs,
                None if decoding else trees[index],
                band,
                reference_of(out, index, orientation),
                _activity(known, shape, header.levels, index),
            )
        else:
            tree = flat_quadtree(band, root_width(band))
        out.append(tree)
        squares, rest = subband_plan(shape, header.levels, index, tree, header.transform_1d)
        for c, q in enumerate(quantized):
            entropy.code_coefficients(coeffs, q, squares, known[c], guides[c], spent[c])
            if squares.order.size:
                view = known[c].reshape(shape)[where]
                debandeletize_bins(view, tree, header.threshold, header.transform_1d)
            entropy.code_coefficients(coeffs, q, rest, known[c], guides[c], spent[c])
    return out, quantized, spent


def new_coders(data: tuple[bytes, bytes, bytes] | None = None) -> tuple[entropy.Coder, ...]:
    sizes = (N_SPLIT_CONTEXTS, N_DIRECTION_CONTEXTS, entropy.coefficient_contexts())
    return tuple(entropy.Coder(n, None if data is None else data[i]) for i, n in enumerate(sizes))


# ---------------------------------------------------------------------------------------------
# Images in and out.


def check_image(array, kind: str, max_memory: int = MAX_MEMORY) -> np.ndarray:
    """Validate an image and return it as float64 ``(H, W, C)``; ``ValueError`` if unusable.

    An image whose encoding would need more than ``max_memory`` bytes
    (:func:`bandelets.bitstream.encoder_memory`) is refused before any work on it (a float64
    array is not copied; another dtype is converted first).
    """
    if kind not in KINDS:
        raise ValueError(f"unknown kind {kind!r}; choose one of {', '.join(KINDS)}")
    try:
        x = np.asarray(array, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"input is not a numeric array ({err})") from None
    if x.ndim == 2:
        x = x[..., None]
    if x.ndim != 3 or not 1 <= x.shape[2] <= 4:
        raise ValueError(f"expected an H x W or H x W x C array with 1 to 4 channels, got shape {x.shape}")
    if x.shape[0] * x.shape[1] < 2:
        raise ValueError(f"image is too small ({x.shape[1]} x {x.shape[0]} pixels)")
    if kind != "image" and x.shape[2] != 3:
        raise ValueError(f"a {kind} needs 3 channels, got {x.shape[2]}")
    need = encoder_memory(*x.shape)
    if need > max_memory:
        raise ValueError(
            f"encoding a {x.shape[1]} x {x.shape[0]} x {x.shape[2]} image needs about "
            f"{need / 2**20:.0f} MiB, above the limit of {max_memory / 2**20:.0f} MiB (max_memory)"
        )
    if not np.all(np.isfinite(x)):
        raise ValueError("input contains NaN or infinite values")
    return x


def _check_options(threshold: float, transform: str, wavelet: str, transform_1d: str) -> None:
    if transform not in TRANSFORMS:
        raise ValueError(f"unknown transform {transform!r}; choose one of {', '.join(TRANSFORMS)}")
    if wavelet not in WAVELETS:
        raise ValueError(f"unknown wavelet {wavelet!r}; choose one of {', '.join(WAVELETS)}")
    if transform_1d not in TRANSFORMS_1D:
        raise ValueError(f"unknown 1D transform {transform_1d!r}; choose one of {', '.join(TRANSFORMS_1D)}")
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError(f"threshold must be a positive number, got {threshold}")


def check_geometry_options(normal_weight: float, extension: str) -> None:
    """``ValueError`` unless ``normal_weight`` and ``extension`` are usable for geometry images."""
    if not (np.isfinite(normal_weight) and MIN_NORMAL_WEIGHT <= normal_weight <= MAX_NORMAL_WEIGHT):
        raise ValueError(f"normal_weight must be from 1/64 to 64, got {normal_weight}")
    check_extension((2, 2), "cdf97", 1, extension)


def _geometry_options(
    kind: str, shape: tuple[int, int], wavelet: str, frames: bool, weight: float, extension: str
) -> dict:
    """The geometry-image fields of the header (``{}`` for other kinds); ``ValueError`` if unusable."""
    if kind != "geometry-image":
        if frames or extension != "symmetric":
            raise ValueError("local frames and the spherical extension apply to geometry images only")
        return {}
    check_geometry_options(weight, extension)
    check_extension(shape, wavelet, 1, extension)  # the encoder then picks levels that fit
    return {"extension": extension, "frames": bool(frames), "normal_weight": float(weight) if frames else 1.0}


@dataclass(frozen=True)
class Encoded:
    """A .bdl file and what the encoder knows about it."""

    data: bytes
    threshold: float
    # Squared quantization error summed over all (padded) coefficients, before any restoration.
    coefficient_sse: float
    # PSNR of the decoded file, when the encoder has already measured it (the restoration does).
    psnr: float | None = None


def encode_at_threshold(coefficients: list[np.ndarray], header: Header) -> Encoded:
    """Encode the channels, given their (padded) wavelet coefficients, at ``header.threshold``.

    Rate control calls this repeatedly with the same coefficients: the wavelet transform is
    done once, the basis search and the coding once per threshold.
    """
    threshold = header.threshold
    before = None
    if header.frames:
        coefficients, before = _local_frames(coefficients, header)
    trees = _best_trees(coefficients, header.levels, threshold, header.transform, header.transform_1d, before)
    bandelets = [
        _apply_trees(c, header.levels, trees, bandeletize, header.transform_1d) for c in coefficients
    ]
    quantized = [quantize(b, threshold) for b in bandelets]
    # Rate-distortion optimised quantization: a first coding pass prices every coefficient in
    # its context, then the bins between 0 and +-1 are chosen again and the image coded again.
    # Not with local frames: the frames of each level were built from the coarser levels as
    # Q_T left them, and the decoder must rebuild exactly those.
    if not header.frames:
        _, _, spent = code_image(new_coders(), header, trees, [q.ravel() for q in quantized])
        approximation = approximation_plan(bandelets[0].shape, header.levels).order
        for b, q, bits in zip(bandelets, quantized, spent, strict=True):
            bits[approximation] = 0.0  # coded as a prediction residual: left alone
            _optimise_bins(b, q, bits.reshape(q.shape), threshold)
    # The weighted normal component's error is the weight times the error it makes.
    scales = (header.normal_weight, 1.0, 1.0) if header.frames else (1.0,) * len(bandelets)
    sse = sum(
        float(np.sum((b - dequantize(q, threshold)) ** 2)) / scale**2
        for b, q, scale in zip(bandelets, quantized, scales, strict=True)
    )
    splits, dirs, coeffs = coders = new_coders()
    code_image(coders, header, trees, [q.ravel() for q in quantized])
    data = pack(header, (splits.finish(), dirs.finish(), coeffs.finish()))
    return Encoded(data, threshold, sse)


#: Lagrange multiplier of the quantization decisions, in T**2 per bit (the search's LAMBDA).
RDOQ_LAMBDA = LAMBDA
#: Bits a significant coefficient spends besides its significance (sign, first magnitude flag).
_SIGN_AND_MAGNITUDE_BITS = 1.5


def _optimise_bins(values: np.ndarray, q: np.ndarray, bits: np.ndarray, threshold: float) -> None:
    """Rate-distortion optimised quantization between 0 and +-1, in place.

    ``Q_T`` decides on magnitude alone; here a coefficient of bin 1 becomes 0, or a value of
    the dead zone above ``PROMOTE_ABOVE T`` becomes +-1, when that lowers
    ``error + RDOQ_LAMBDA T**2 bits``. The bits come from a first coding pass: a coefficient's
    ideal code length prices its own choice, and the probability of significance its context
    had (``2**-bits`` for a zero, about ``2**(1.5 - bits)`` for a +-1) prices the other one.

    Parameters
    ----------
    values : ndarray of float, shape (H, W)
        The coefficients quantized.
    q : ndarray of int32, shape (H, W)
        Their bin indices; modified.
    bits : ndarray of float, shape (H, W)
        Ideal code length of each coefficient in the first pass; 0 where not to be touched.
    threshold : float
    """
    price = RDOQ_LAMBDA * threshold * threshold
    a = np.abs(values)
    # Error removed by coding +-1 instead of 0.
    gain = a * a - (a - (1.0 + RECONSTRUCTION) * threshold) ** 2
    ones = (np.abs(q) == 1) & (bits > 0)
    significant = np.clip(2.0 ** (_SIGN_AND_MAGNITUDE_BITS - bits[ones]), 0.0, 0.5)
    saved = bits[ones] + np.log2(1.0 - significant)
    drop = np.zeros(q.shape, bool)
    drop[ones] = gain[ones] < price * saved
    zeros = (q == 0) & (bits > 0) & (a > PROMOTE_ABOVE * threshold)
    significant = np.clip(1.0 - 2.0 ** -bits[zeros], 1e-6, 1.0)
    extra = _SIGN_AND_MAGNITUDE_BITS - np.log2(significant) - bits[zeros]
    promote = np.zeros(q.shape, bool)
    promote[zeros] = gain[zeros] > price * extra
    q[drop] = 0
    q[promote] = np.sign(values[promote]).astype(q.dtype)


def _local_frames(coefficients: list[np.ndarray], header: Header):
    """The coefficients to turn into local frames, and the ``before`` hook of :func:`_best_trees`
    that turns each level just before the basis search reaches it.

    The frames of a level come from the approximation and the coarser levels exactly as the
    decoder will decode them (:func:`bandelets.frames.to_global`): quantized with the trees
    already chosen, dequantized and turned back.
    """
    t, levels, t1d = header.threshold, header.levels, header.transform_1d
    args = (header.wavelet, levels, header.extension)
    shape = coefficients[0].shape
    h, w = shape[0] >> levels, shape[1] >> levels
    local = [c.copy() for c in coefficients]
    decoded = [np.zeros(shape) for _ in coefficients]  # what the decoder has so far, global frame
    for c, d in zip(coefficients, decoded, strict=True):
        d[:h, :w] = dequantize(quantize(c[:h, :w], t), t)
    slices = subband_slices(shape, levels)
    turned = []  # the frames of the level turned last

    def before(index: int, trees: list) -> None:
        if index % 3:
            return
        if turned:  # decode the level just searched, as the decoder will
            for i in range(index - 3, index):
                where = slices[i][2]
                for c, d in zip(local, decoded, strict=True):
                    q = quantize(bandeletize(c[where], trees[i], t1d), t)
                    d[where] = debandeletize(dequantize(q, t), trees[i], t1d)
            frames.rotate(
                decoded, turned[-1], slices[index - 1][0], levels, header.normal_weight, local=False
            )
        level = slices[index][0]
        turned[:] = [frames.level_frames(decoded, level, *args, header.kind)]
        frames.rotate(local, turned[-1], level, levels, header.normal_weight, local=True)

    return local, before


def wavelet_coefficients(
    x: np.ndarray, wavelet: str, levels: int, extension: str = "symmetric"
) -> list[np.ndarray]:
    """Padded, normalised wavelet coefficients of every channel of ``x`` (H, W, C)."""
    return [wavedec(_pad(x[..., k], levels), wavelet, levels, extension) for k in range(x.shape[2])]


def decode(data: bytes, *, restore: bool = True, max_memory: int = MAX_MEMORY, **limits) -> np.ndarray:
    """Decode a .bdl file.

    Parameters
    ----------
    data : bytes
        The whole file.
    restore : bool
        Run the restoration iterations the file asks for (:mod:`bandelets.restoration`).
        False: plain dequantization, a faster decode of lower quality (a preview).
    max_memory : int
        Refuse a file whose decoding needs more than this many bytes (estimated from its
        header, see :func:`bandelets.bitstream.check_memory`; default 2 GiB).
    **limits
        ``max_side`` and ``max_samples`` (see :func:`bandelets.bitstream.unpack`).

    Returns
    -------
    ndarray, float64, shape (H, W) for one channel or (H, W, C); a normal map's vectors are
    renormalised to unit length.

    Raises
    ------
    FormatError
        For any corrupt, truncated or unsupported file.
    """
    header, streams = unpack(bytes(data), **limits)
    return decode_parsed(header, streams, restore=restore, max_memory=max_memory)


def decode_parsed(
    header: Header,
    streams: tuple[bytes, bytes, bytes],
    *,
    restore: bool = True,
    max_memory: int = MAX_MEMORY,
) -> np.ndarray:
    """Decode a file already split by :func:`bandelets.bitstream.unpack` (options of :func:`decode`)."""
    if not restore:
        header = replace(header, restoration=0)
    check_memory(header, max_memory)
    trees, quantized = _decoded_bins(header, streams)
    channels = next(islice(_restorations(header, trees, quantized), header.restoration, None))
    return _output(channels, header)


def _decoded_bins(header: Header, streams: tuple[bytes, bytes, bytes]) -> tuple[list, list[np.ndarray]]:
    """The quadtrees and the bin indices, shape (H', W') per channel, that the streams hold."""
    coders = new_coders(streams)
    try:
        trees, quantized, _ = code_image(coders, header)
        for coder in coders:
            coder.check()
    except entropy.CorruptStream as err:
        raise FormatError(f"corrupt .bdl file: {err}") from None
    shape = padded_shape((header.height, header.width), header.levels)
    return trees, [q.reshape(shape) for q in quantized]


def _restorations(header: Header, trees: list, quantized: list[np.ndarray]):
    """The channels after 0, 1, 2, ... restoration iterations (:func:`bandelets.restoration.iterate`)."""
    unit = header.kind == "normal-map" and header.channels == 3
    return restoration.iterate(
        quantized,
        header.threshold,
        *_transforms(header, trees, quantized),
        unit_vectors=(header.height, header.width) if unit else None,
    )


#: Pixels from which the restoration transforms the channels in parallel threads (independent
#: transforms; numpy lets go of the GIL on large arrays): a two-channel crease map decodes
#: 1.3 times faster at 2048 x 2048 and 1024 x 1024, 1.1 times at 512 x 512, but 1.4 times slower
#: at 256 x 256, where the threads mostly wait for each other (``benchmarks/speed.py``).
_THREADS_FROM = 512 * 512


def _channel_map(header: Header):
    """``each(function, channels)``, the list of ``function(channel)``: in one thread per channel
    from :data:`_THREADS_FROM` pixels on."""
    if header.channels < 2 or header.height * header.width < _THREADS_FROM:
        return lambda function, channels: [function(channel) for channel in channels]
    pool = ThreadPoolExecutor(max_workers=header.channels)
    return lambda function, channels: list(pool.map(function, channels))


def _transforms(header: Header, trees: list, quantized: list[np.ndarray]):
    """The file's transform of the (padded) channels, ``(C, H, W)`` to ``(C, H, W)``, and its
    inverse. With local frames, those of every level are the ones the decoder finds from the
    dequantized bins ``quantized`` (:func:`bandelets.frames.to_global`), fixed from then on."""
    t1d, levels, args = header.transform_1d, header.levels, (header.wavelet, header.levels, header.extension)
    each = _channel_map(header)
    level_frames = None
    if header.frames:
        decoded = [
            _apply_trees(dequantize(q, header.threshold), levels, trees, debandeletize, t1d)
            for q in quantized
        ]
        level_frames = frames.to_global(decoded, *args, header.normal_weight, header.kind)

    def analysis(x: np.ndarray) -> np.ndarray:
        c = each(lambda channel: wavedec(channel, *args), x)
        if level_frames is not None:
            frames.rotate_levels(c, level_frames, levels, header.normal_weight, local=True)
        return np.array(each(lambda channel: _apply_trees(channel, levels, trees, bandeletize, t1d), c))

    def synthesis(c: np.ndarray) -> np.ndarray:
        c = each(lambda channel: _apply_trees(channel, levels, trees, debandeletize, t1d), c)
        if level_frames is not None:
            frames.rotate_levels(c, level_frames, levels, header.normal_weight, local=False)
        return np.array(each(lambda channel: waverec(channel, *args), c))

    return analysis, synthesis


def _output(channels, header: Header) -> np.ndarray:
    """What :func:`decode` returns, from the decoded (padded) channels."""
    out = np.stack([c[: header.height, : header.width] for c in channels], axis=-1)
    if not np.all(np.isfinite(out)):
        raise FormatError("corrupt .bdl file: the decoded values overflow")
    if header.kind == "normal-map":
        if header.channels == 2:
            out = np.concatenate([out, _rebuilt_z(out)], axis=-1)
        out = metrics.unit_vectors(out)
    return out[..., 0] if header.channels == 1 else out


def _rebuilt_z(xy: np.ndarray) -> np.ndarray:
    """``z = sqrt(1 - x^2 - y^2)`` (0 where the decoded ``x, y`` lie outside the unit disc), shape
    (H, W, 1), of decoded normals ``xy`` of shape (H, W, 2)."""
    return np.sqrt(np.maximum(1.0 - np.sum(xy * xy, axis=-1, keepdims=True), 0.0))


def encode(
    array,
    *,
    bpp: float | None = None,
    threshold: float | None = None,
    psnr: float | None = None,
    transform: str = "bandelet",
    kind: str = "image",
    wavelet: str = "cdf97",
    transform_1d: str = "alpert2",
    depth: int = 0,
    frames: bool = False,
    normal_weight: float = 2.0,
    extension: str = "symmetric",
    restore: bool = True,
    progress: bool = False,
    max_memory: int = MAX_MEMORY,
) -> bytes:
    """Compress an image, normal map or geometry image into a .bdl file.

    Parameters
    ----------
    array : array_like, shape (H, W) or (H, W, C), C <= 4
        Values as they are (a normal map: vectors in [-1, 1]; a geometry image: positions).
        A normal map whose vectors all have ``z >= 0`` is coded as ``x, y`` only (its decoder
        rebuilds ``z``); otherwise as three channels, in local frames around the coarser
        decoded normals (:mod:`bandelets.frames`, normal weight
        :data:`bandelets.frames.NORMAL_MAP_WEIGHT`).
    bpp, threshold, psnr : float, exactly one
        Target rate in bits per pixel (the file lands within 3 % below it), quantization
        threshold ``T``, or target PSNR in dB (:func:`bandelets.metrics.psnr` for ``kind``).
    transform : {"bandelet", "wavelet"}
        ``"wavelet"`` forces every square to NULL: the same codec without geometry.
    kind : {"image", "normal-map", "geometry-image"}
        A normal map is renormalised to unit vectors before coding and after decoding.
    wavelet : str
        See :data:`bandelets.wavelets.WAVELETS`, or ``"auto"``: encode with each of
        :data:`AUTO_CANDIDATES` and keep the better file (twice the time).
    transform_1d : {"alpert2", "haar"}
        1D transform along the directions.
    depth : {0, 8, 16}
        Bit depth of the PNG the values came from (0: float), recorded for decoding to PNG.
    frames : bool
        Geometry images only (normal maps choose by themselves, see ``array``): code the detail
        coefficients of each level in local frames (normal, tangents) estimated from the decoded
        coarser levels (:mod:`bandelets.frames`).
    normal_weight : float
        With ``frames``: precision given to the normal component over the tangential ones,
        from 1/64 to 64.
    extension : {"symmetric", "spherical"}
        Geometry images only: boundary extension of the wavelet; ``"spherical"`` for an
        octahedral spherical geometry image (square, even side: each edge is glued to itself
        reversed, see :mod:`bandelets.surfaces.octahedral`).
    restore : bool
        Let the decoder restore the image (:mod:`bandelets.restoration`) for as many
        iterations as bring it closest to ``array`` (none if that is best).
        Costs no bits; the encoder and decoder then take longer (about 5 ms per iteration for
        256 x 256 x 2).
    progress : bool
        Progress bar during rate control.
    max_memory : int
        Refuse (``ValueError``) an image whose encoding would need more than this many bytes.

    Returns
    -------
    bytes
    """
    return encode_with_stats(
        array,
        bpp=bpp,
        threshold=threshold,
        psnr=psnr,
        transform=transform,
        kind=kind,
        wavelet=wavelet,
        transform_1d=transform_1d,
        depth=depth,
        frames=frames,
        normal_weight=normal_weight,
        extension=extension,
        restore=restore,
        progress=progress,
        max_memory=max_memory,
    ).data


def encode_with_stats(
    array,
    *,
    bpp=None,
    threshold=None,
    psnr=None,
    transform="bandelet",
    kind="image",
    wavelet="cdf97",
    transform_1d="alpert2",
    depth=0,
    frames=False,
    normal_weight=2.0,
    extension="symmetric",
    restore=True,
    progress=False,
    max_memory=MAX_MEMORY,
) -> Encoded:
    """:func:`encode`, returning also the threshold used, the predicted error and (when the
    encoder chose the restoration) the PSNR of the decoded file."""
    if wavelet == AUTO_WAVELET:
        return _best_of_wavelets(
            array,
            bpp=bpp,
            threshold=threshold,
            psnr=psnr,
            transform=transform,
            kind=kind,
            transform_1d=transform_1d,
            depth=depth,
            frames=frames,
            normal_weight=normal_weight,
            extension=extension,
            restore=restore,
            progress=progress,
            max_memory=max_memory,
        )
    x = check_image(array, kind, max_memory)
    if kind == "normal-map":
        x = metrics.unit_vectors(x)
    targets = [v for v in (bpp, threshold, psnr) if v is not None]
    if len(targets) != 1:
        raise ValueError("give exactly one of bpp, threshold or psnr")
    if depth not in (0, 8, 16):
        raise ValueError(f"depth must be 0, 8 or 16, got {depth}")
    if wavelet not in WAVELETS:
        choices = ", ".join((*WAVELETS, AUTO_WAVELET))
        raise ValueError(f"unknown wavelet {wavelet!r}; choose one of {choices}")
    _check_options(1.0 if threshold is None else threshold, transform, wavelet, transform_1d)
    levels = max_levels(x.shape[:2])
    geometry = _geometry_options(kind, x.shape[:2], wavelet, frames, normal_weight, extension)
    if extension == "spherical":  # no padding: the fold must stay on the image's border
        while levels > 1 and x.shape[0] % (1 << levels):
            levels -= 1
    # A unit normal with z >= 0 is fixed by x and y (as BC5 stores normal maps): z costs no bits.
    coded = x[..., :2] if kind == "normal-map" and np.all(x[..., 2] >= 0) else x
    if kind == "normal-map":  # three channels: always in local frames
        geometry = implied_options(kind, coded.shape[2])
    coefficients = wavelet_coefficients(coded, wavelet, levels, extension)

    def encode_at(t: float) -> Encoded:
        header = Header(
            x.shape[0],
            x.shape[1],
            coded.shape[2],
            kind,
            transform,
            wavelet,
            levels,
            t,
            depth,
            transform_1d,
            **geometry,
        )
        return encode_at_threshold(coefficients, header)

    magnitudes = np.abs(np.concatenate([c.ravel() for c in coefficients]))
    t_max = 2.0 * float(magnitudes.max()) * max(1.0, geometry.get("normal_weight", 1.0)) + 1e-300
    reference = x[..., 0] if x.shape[2] == 1 else x

    def finished(encoded: Encoded) -> Encoded:
        return _with_restoration(encoded, reference, max_memory) if restore else encoded

    if threshold is not None:
        return finished(encode_at(float(threshold)))
    if bpp is not None:
        if not (np.isfinite(bpp) and bpp > 0):
            raise ValueError(f"bpp must be a positive number, got {bpp}")
        target = int(bpp * x.shape[0] * x.shape[1] / 8)
        if target < HEADER_BYTES:
            raise ValueError(
                f"target of {bpp:g} bpp ({target} bytes) cannot be reached: a .bdl file needs at least "
                f"{HEADER_BYTES} bytes of header"
            )
        model = ratecontrol.size_model(magnitudes)
        return finished(ratecontrol.for_size(encode_at, target, t_max, model, progress))
    if not np.isfinite(psnr):
        raise ValueError(f"psnr must be a finite number, got {psnr}")
    # Start where a uniform quantizer's error would meet the target.
    t_guess = min(t_max, 2.0 * metrics.peak(reference, kind) * 10 ** (-psnr / 20)) or t_max / 1e3

    def quality(encoded: Encoded) -> float:
        if encoded.psnr is not None:  # measured on the restored image, as decode returns it
            return encoded.psnr
        # Our own file: only the caller's memory limit applies, not the limits on foreign files.
        decoded = decode(encoded.data, max_memory=max_memory, max_side=2**32, max_samples=2**64)
        return metrics.psnr(reference, decoded, kind)

    # Each try is restored: the target is met by the restored image, with the smallest file.
    return ratecontrol.for_quality(
        lambda t: finished(encode_at(t)), quality, float(psnr), t_max, t_guess, progress
    )


#: The encoder stops trying more restoration iterations this many after the best so far.
_RESTORATION_PATIENCE = 10


def _with_restoration(encoded: Encoded, reference: np.ndarray, max_memory: int) -> Encoded:
    """``encoded`` with the number of restoration iterations that decodes closest to
    ``reference`` (the image as :func:`decode` should return it) written into its header."""
    header, streams = unpack(encoded.data, max_side=2**32, max_samples=2**64)
    try:
        check_memory(replace(header, restoration=1), max_memory)
    except FormatError:  # the decoder could not afford it either
        return encoded
    trees, quantized = _decoded_bins(header, streams)
    best, best_psnr = 0, -np.inf
    measure = metrics.psnr_against(reference, header.kind)
    for n, channels in enumerate(_restorations(header, trees, quantized)):
        value = measure(_output(channels, header))
        if value > best_psnr:
            best, best_psnr = n, value
        if n == restoration.MAX_ITERATIONS or n - best >= _RESTORATION_PATIENCE:
            break
    if best == 0:
        return replace(encoded, psnr=best_psnr)
    return replace(encoded, data=pack(replace(header, restoration=best), streams), psnr=best_psnr)


#: The ``wavelet`` that lets the encoder choose, per image and target, among
#: :data:`AUTO_CANDIDATES`.
AUTO_WAVELET = "auto"
#: CDF 9/7 is best on smooth content; Haar on piecewise-constant content (the facets of a CAD
#: normal map) once the rate is high enough to code the creases exactly.
AUTO_CANDIDATES = ("cdf97", "haar")


def _best_of_wavelets(array, *, bpp, threshold, psnr, kind, max_memory, **options) -> Encoded:
    """Encode with each wavelet of :data:`AUTO_CANDIDATES` and keep the best file.

    For a rate target, the one whose decoded image has the higher PSNR; for a quality target
    the smaller file; at a fixed threshold the smaller ``error + LAMBDA T**2 bits``.
    """
    # The spherical extension exists for CDF 9/7 only.
    candidates = AUTO_CANDIDATES if options.get("extension", "symmetric") == "symmetric" else ("cdf97",)
    files = [
        encode_with_stats(
            array,
            bpp=bpp,
            threshold=threshold,
            psnr=psnr,
            kind=kind,
            wavelet=w,
            max_memory=max_memory,
            **options,
        )
        for w in candidates
    ]
    if psnr is not None:
        return min(files, key=lambda f: len(f.data))
    if threshold is not None:
        return min(files, key=lambda f: f.coefficient_sse + LAMBDA * f.threshold**2 * 8 * len(f.data))
    x = check_image(array, kind, max_memory)
    reference = metrics.unit_vectors(x) if kind == "normal-map" else (x[..., 0] if x.shape[2] == 1 else x)
    limits = dict(max_memory=max_memory, max_side=2**32, max_samples=2**64)
    return max(files, key=lambda f: metrics.psnr(reference, decode(f.data, **limits), kind))
