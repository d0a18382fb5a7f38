"""The bandelet codec: the transform of the paper end to end, and .bdl encode / decode.

``forward`` and ``inverse`` are the paper's bandelet transform of one channel (steps (1) to
(10)): pad, 2D wavelet transform, then in every detail subband the Lagrangian search of
the best direction of every dyadic square, the best quadtree, and the bandeletization.
``encode`` and ``decode`` add quantization (Q_T), entropy coding and the file format, for
images of one to four channels; rate control lives in :mod:`bandelets.ratecontrol`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import entropy
from .bandeletize import TRANSFORMS_1D, bandeletize, debandeletize
from .bitstream import KINDS, TRANSFORMS, FormatError, Header, pack, unpack
from .lagrangian import LAMBDA, best_directions
from .layout import coding_plan
from .quadtree import MIN_WIDTH, best_quadtree, flat_quadtree, root_width
from .quantize import MAX_INDEX, dequantize, quantize
from .treecoding import N_DIRECTION_CONTEXTS, N_SPLIT_CONTEXTS, code_trees, predicted_directions, reference_of
from .wavelets import WAVELETS, max_levels, padded_shape, subband_slices, wavedec, waverec

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


def _best_trees(coefficients: list[np.ndarray], levels: int, threshold: float, transform: str,
                transform_1d: str) -> list:
    """Best quadtree and directions of every detail subband (paper steps (3) to (8), (10)).

    ``coefficients`` holds the wavelet coefficients of every channel; they share one geometry.
    """
    trees = []
    for index, (_, orientation, where) in enumerate(subband_slices(coefficients[0].shape, levels)):
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
            predicted = predicted_directions(reference, (covered.shape[1] // width, covered.shape[2] // width), width)
            cost, d = best_directions(covered, width, threshold, transform_1d=transform_1d, predicted=predicted)
            costs.append(cost)
            dirs.append(d)
            width *= 2
        trees.append(best_quadtree(costs, dirs, LAMBDA * threshold * threshold))
    return trees


def _apply_trees(coefficients: np.ndarray, levels: int, trees: list, transform_fn,
                 transform_1d: str) -> np.ndarray:
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
    x = check_image(channel, "image")[..., 0]
    _check_options(threshold, transform, wavelet, transform_1d)
    levels = levels or max_levels(x.shape)
    c = wavedec(_pad(x, levels), wavelet, levels)
    trees = _best_trees([c], levels, threshold, transform, transform_1d)
    return Bandelets(_apply_trees(c, levels, trees, bandeletize, transform_1d), trees, x.shape, wavelet,
                     levels, threshold, transform_1d)


def inverse(b: Bandelets) -> np.ndarray:
    """Inverse bandelet transform: the channel, shape ``b.shape``."""
    c = _apply_trees(b.coefficients, b.levels, b.trees, debandeletize, b.transform_1d)
    return waverec(c, b.wavelet, b.levels)[: b.shape[0], : b.shape[1]]


def code_channel(coder: entropy.Coder, q: np.ndarray, plan, trees: list, header: Header) -> np.ndarray:
    """Code (or decode into ``q``) the coefficients of one channel, stage by stage.

    After the bandelet squares of a subband, the contexts are given the wavelet
    coefficients those squares decode to (see :mod:`bandelets.layout`).

    Returns
    -------
    ndarray, shape (H * W,): ideal code length of every coefficient, in bits.
    """
    shape = padded_shape((header.height, header.width), header.levels)
    known = np.zeros(q.shape, np.int64)
    spent = np.zeros(q.shape)
    bands = subband_slices(shape, header.levels)
    start = 0
    for stop, band in plan.stages + [(plan.order.shape[0], None)]:
        entropy.code_coefficients(coder, q, plan, known, spent, start, stop)
        start = stop
        if band is not None:
            where = bands[band][2]
            view = known.reshape(shape)[where]
            wavelets = debandeletize(dequantize(view, header.threshold), trees[band], header.transform_1d)
            view[...] = np.clip(np.fix(wavelets / header.threshold), -MAX_INDEX, MAX_INDEX)
    return spent


def _new_coders(data: tuple[bytes, bytes, bytes] | None = None) -> tuple[entropy.Coder, ...]:
    sizes = (N_SPLIT_CONTEXTS, N_DIRECTION_CONTEXTS, entropy.coefficient_contexts())
    return tuple(entropy.Coder(n, None if data is None else data[i]) for i, n in enumerate(sizes))


# ---------------------------------------------------------------------------------------------
# Images in and out.


def check_image(array, kind: str) -> np.ndarray:
    """Validate an image and return it as float64 ``(H, W, C)``; ``ValueError`` if unusable."""
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


def _renormalise(vectors: np.ndarray) -> np.ndarray:
    """Unit vectors; zero vectors (no direction left after coding) become +z."""
    norm = np.linalg.norm(vectors, axis=-1, keepdims=True)
    out = np.where(norm > 0, vectors / np.where(norm > 0, norm, 1), 0.0)
    out[..., 2][norm[..., 0] == 0] = 1.0
    return out


@dataclass(frozen=True)
class Encoded:
    """A .bdl file and what the encoder knows about it."""

    data: bytes
    threshold: float
    coefficient_sse: float  # squared quantization error summed over all (padded) coefficients


def encode_at_threshold(wavelet_coefficients: list[np.ndarray], header: Header) -> Encoded:
    """Encode the channels, given their (padded) wavelet coefficients, at ``header.threshold``.

    Rate control calls this repeatedly with the same coefficients: the wavelet transform is
    done once, the basis search and the coding once per threshold.
    """
    threshold = header.threshold
    splits, dirs, coeffs = _new_coders()
    sse = 0.0
    trees = _best_trees(wavelet_coefficients, header.levels, threshold, header.transform, header.transform_1d)
    shape = wavelet_coefficients[0].shape
    if header.transform == "bandelet":
        code_trees(splits, dirs, trees, shape, header.levels)
    plan = coding_plan(shape, header.levels, trees, header.transform_1d)
    for c in wavelet_coefficients:
        b = _apply_trees(c, header.levels, trees, bandeletize, header.transform_1d)
        q = quantize(b, threshold)
        sse += float(np.sum((b - dequantize(q, threshold)) ** 2))
        code_channel(coeffs, q.ravel(), plan, trees, header)
    data = pack(header, (splits.finish(), dirs.finish(), coeffs.finish()))
    return Encoded(data, threshold, sse)


def wavelet_coefficients(x: np.ndarray, wavelet: str, levels: int) -> list[np.ndarray]:
    """Padded, normalised wavelet coefficients of every channel of ``x`` (H, W, C)."""
    return [wavedec(_pad(x[..., k], levels), wavelet, levels) for k in range(x.shape[2])]


def decode(data: bytes, **limits) -> np.ndarray:
    """Decode a .bdl file.

    Parameters
    ----------
    data : bytes
        The whole file.
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
    return decode_parsed(header, streams)


def decode_parsed(header: Header, streams: tuple[bytes, bytes, bytes]) -> np.ndarray:
    """Decode a file already split by :func:`bandelets.bitstream.unpack`."""
    splits, dirs, coeffs = _new_coders(streams)
    shape = padded_shape((header.height, header.width), header.levels)
    band_shapes = [(r.stop - r.start, c.stop - c.start) for *_, (r, c) in subband_slices(shape, header.levels)]
    channels = []
    try:
        if header.transform == "bandelet":
            trees = code_trees(splits, dirs, None, shape, header.levels)
        else:
            trees = [flat_quadtree(band, root_width(band)) for band in band_shapes]
        plan = coding_plan(shape, header.levels, trees, header.transform_1d)
        for _ in range(header.channels):
            q = np.zeros(shape[0] * shape[1], np.int32)
            code_channel(coeffs, q, plan, trees, header)
            b = Bandelets(dequantize(q.reshape(shape), header.threshold), trees,
                          (header.height, header.width), header.wavelet, header.levels, header.threshold,
                          header.transform_1d)
            channels.append(inverse(b))
        for coder in (splits, dirs, coeffs):
            coder.check()
    except entropy.CorruptStream as err:
        raise FormatError(f"corrupt .bdl file: {err}") from None
    out = np.stack(channels, axis=-1)
    if header.kind == "normal-map":
        out = _renormalise(out)
    return out[..., 0] if header.channels == 1 else out


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
    progress: bool = False,
) -> bytes:
    """Compress an image, normal map or geometry image into a .bdl file.

    Parameters
    ----------
    array : array_like, shape (H, W) or (H, W, C), C <= 4
        Values as they are (a normal map: vectors in [-1, 1]; a geometry image: positions).
    bpp, threshold, psnr : float, exactly one
        Target rate in bits per pixel (the file lands within 3 % below it), quantization
        threshold ``T``, or target PSNR in dB (:func:`bandelets.metrics.psnr` for ``kind``).
    transform : {"bandelet", "wavelet"}
        ``"wavelet"`` forces every square to NULL: the same codec without geometry.
    kind : {"image", "normal-map", "geometry-image"}
        A normal map is renormalised to unit vectors before coding and after decoding.
    wavelet : str
        See :data:`bandelets.wavelets.WAVELETS`.
    transform_1d : {"alpert2", "haar"}
        1D transform along the directions.
    depth : {0, 8, 16}
        Bit depth of the PNG the values came from (0: float), recorded for decoding to PNG.
    progress : bool
        Progress bar during rate control.

    Returns
    -------
    bytes
    """
    return encode_with_stats(array, bpp=bpp, threshold=threshold, psnr=psnr, transform=transform,
                             kind=kind, wavelet=wavelet, transform_1d=transform_1d, depth=depth,
                             progress=progress).data


def encode_with_stats(array, *, bpp=None, threshold=None, psnr=None, transform="bandelet",
                      kind="image", wavelet="cdf97", transform_1d="alpert2", depth=0,
                      progress=False) -> Encoded:
    """:func:`encode`, returning also the threshold used and the predicted error."""
    from . import metrics, ratecontrol

    x = check_image(array, kind)
    if kind == "normal-map":
        x = metrics.unit_vectors(x)
    targets = [v for v in (bpp, threshold, psnr) if v is not None]
    if len(targets) != 1:
        raise ValueError("give exactly one of bpp, threshold or psnr")
    if depth not in (0, 8, 16):
        raise ValueError(f"depth must be 0, 8 or 16, got {depth}")
    _check_options(threshold or 1.0, transform, wavelet, transform_1d)
    levels = max_levels(x.shape[:2])
    coefficients = wavelet_coefficients(x, wavelet, levels)

    def encode_at(t: float) -> Encoded:
        header = Header(x.shape[0], x.shape[1], x.shape[2], kind, transform, wavelet, levels, t, depth,
                        transform_1d)
        return encode_at_threshold(coefficients, header)

    t_max = 2.0 * max(float(np.max(np.abs(c))) for c in coefficients) + 1e-300
    if threshold is not None:
        return encode_at(float(threshold))
    if bpp is not None:
        if not (np.isfinite(bpp) and bpp > 0):
            raise ValueError(f"bpp must be a positive number, got {bpp}")
        target = int(bpp * x.shape[0] * x.shape[1] / 8)
        return ratecontrol.for_size(encode_at, target, t_max, progress)
    if not np.isfinite(psnr):
        raise ValueError(f"psnr must be a finite number, got {psnr}")
    reference = x[..., 0] if x.shape[2] == 1 else x

    def quality(data: bytes) -> float:
        return metrics.psnr(reference, decode(data), kind)

    return ratecontrol.for_quality(encode_at, quality, float(psnr), t_max, progress)
