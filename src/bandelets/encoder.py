"""Encoding of .bdl files: validation, the basis search, quantization with its rate-distortion
optimisation, entropy coding, the choice of the restoration, and the ``auto`` wavelet.

Rate control (a target rate or PSNR) lives in :mod:`bandelets.ratecontrol`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import partial
from itertools import islice
from typing import Literal

import numpy as np

from . import directional, frames, loopfilter, lossless, metrics, normalmaps, ratecontrol, riesz, tiling
from .bandeletize import bandeletize, debandeletize
from .bitstream import (
    DEFAULT_NORMAL_WEIGHT,
    DEFAULT_TRANSFORM_1D,
    DEFAULT_WAVELET,
    HEADER_BYTES,
    MAX_MEMORY,
    MAX_RESTORATION,
    MAX_THRESHOLD,
    MAX_WORK,
    MIN_THRESHOLD,
    FormatError,
    Header,
    Kind,
    Transform1D,
    Wavelet,
    implied_options,
    pack,
    unpack,
)
from .blasthreads import one_blas_thread
from .coding import code_image, code_lifting, new_coders
from .decoder import decode, decoded_bins, decoded_image, restorations
from .files import as_read, to_samples
from .lagrangian import LAMBDA
from .layout import approximation_plan
from .levelchoice import choose_levels, levels_to_try
from .memory import check_encodable, check_memory, restoration_work
from .options import AUTO_WAVELET, EncodeOptions, check_image, check_targets, geometry_options
from .progress import Progress
from .quantize import dequantize, optimise_bins, quantize
from .transform import apply_trees, best_trees, padded_channels, wavelet_coefficients
from .treememo import TreeMemo
from .wavelets import max_levels, subband_slices, wavedec

__all__ = ["AUTO_CANDIDATES", "Encoded", "encode", "encode_with_stats", "encode_at_threshold"]

#: Lagrange multiplier of the choice between 0 and +-1 (:func:`bandelets.quantize.optimise_bins`),
#: below the basis search's: its prices come from a first pass, and a coefficient dropped to 0
#: also makes its neighbours' contexts cheaper, which they do not count. 0.7 LAMBDA gained +0.04
#: to +0.05 dB BD-PSNR on the crease and bevel maps (-0.05 on the bumps, 0.00 to -0.01 on the
#: acacia door), 0.5 LAMBDA less: BENCHMARKS, "A step per wavelet level".
RDOQ_LAMBDA = 0.7 * LAMBDA


@dataclass(frozen=True)
class Encoded:
    """A .bdl file and what the encoder knows about it."""

    data: bytes
    threshold: float
    # Squared quantization error summed over all (padded) coefficients, before any restoration.
    coefficient_sse: float
    # PSNR of the decoded file at the source's depth, when the encoder has already measured it
    # (the restoration does), and what decode returns for the file.
    psnr: float | None = None
    decoded: np.ndarray | None = field(default=None, repr=False, compare=False)
    # What the file holds, as the decoder will find it: the quadtrees and the bins of every
    # channel, shape (H', W') (for the choice of the restoration, without decoding the file).
    header: Header | None = field(default=None, repr=False, compare=False)
    trees: list | None = field(default=None, repr=False, compare=False)
    bins: list | None = field(default=None, repr=False, compare=False)
    lifting: list | None = field(default=None, repr=False, compare=False)
    # A tiled file's angular error (:mod:`bandelets.tiling`), measured tile by tile: its decoded
    # image is not kept.
    angles: metrics.AngularError | None = field(default=None, repr=False, compare=False)


def encode_at_threshold(
    coefficients: list[np.ndarray], header: Header, lifting: list | None = None, search=best_trees
) -> Encoded:
    """Encode the channels, given their (padded) wavelet coefficients, at ``header.threshold``.

    Rate control calls this repeatedly with the same coefficients: the wavelet transform is
    done once, the basis search and the coding once per threshold. ``lifting``: the directions
    of the levels lifted along directions (:func:`bandelets.directional.analysis`) when
    ``header.lifting``. ``search``: :func:`bandelets.transform.best_trees` or a rate-control
    loop's :meth:`bandelets.treememo.TreeMemo.search`.
    """
    threshold = header.threshold
    before, source = None, coefficients
    if header.frames:
        coefficients, before = _local_frames(source, header)
    trees = search(coefficients, header.levels, threshold, header.transform, header.transform_1d, before)
    bandelets = [apply_trees(c, header.levels, trees, bandeletize, header.transform_1d) for c in coefficients]
    quantized = [quantize(b, threshold) for b in bandelets]
    # Rate-distortion optimised quantization: a first coding pass prices every coefficient in
    # its context, then the bins between 0 and +-1 are chosen again and the image coded again.
    prices = _prices(quantized, header, trees)
    if header.frames:
        # The frames of a level are made from the coarser levels as the decoder decodes them, so
        # from the bins chosen again: the levels are turned again, coarse to fine, each one's
        # bins chosen again (same trees, the first pass's prices) before the next one's frames
        # are made (+0.2 to +0.3 dB BD-PSNR on the normal maps of the fandisk and bunny meshes).
        del bandelets, quantized
        coefficients, before = _local_frames(source, header, prices)
        for index in range(len(trees)):
            before(index, trees)
        bandelets = [
            apply_trees(c, header.levels, trees, bandeletize, header.transform_1d) for c in coefficients
        ]
        quantized = [quantize(b, threshold) for b in bandelets]
    del coefficients, source
    for b, q, bits in zip(bandelets, quantized, prices, strict=True):
        optimise_bins(b, q, bits, threshold, RDOQ_LAMBDA)
    del prices
    # The weighted normal component's error is the weight times the error it makes.
    scales = (header.normal_weight, 1.0, 1.0) if header.frames else (1.0,) * len(bandelets)
    sse = sum(
        float(np.sum((b - dequantize(q, threshold)) ** 2)) / scale**2
        for b, q, scale in zip(bandelets, quantized, scales, strict=True)
    )
    del bandelets  # not held while coding: the peak of a large image's encoding
    splits, dirs, coeffs = coders = new_coders()
    trees, _, _ = code_image(coders, header, trees, [q.ravel() for q in quantized])
    code_lifting(dirs, header, lifting)
    data = pack(header, (splits.finish(), dirs.finish(), coeffs.finish()))
    return Encoded(data, threshold, sse, header=header, trees=trees, bins=quantized, lifting=lifting)


def _prices(quantized: list, header: Header, trees: list) -> list[np.ndarray]:
    """The bits a first coding pass spends on every coefficient of ``quantized``, shape (H', W')
    per channel, 0 on the approximation (coded as a prediction residual: left alone), as
    :func:`bandelets.quantize.optimise_bins` takes them."""
    _, _, spent = code_image(new_coders(), header, trees, [q.ravel() for q in quantized])
    approximation = approximation_plan(quantized[0].shape, header.levels).order
    for bits in spent:
        bits[approximation] = 0.0
    return [bits.reshape(quantized[0].shape) for bits in spent]


def _local_frames(coefficients: list[np.ndarray], header: Header, prices: list | None = None):
    """The coefficients to turn into local frames, and the ``before`` hook of :func:`best_trees`
    that turns each level just before the basis search reaches it.

    The frames of a level come from the approximation and the coarser levels exactly as the
    decoder will decode them (:func:`bandelets.frames.to_global`): quantized with the trees
    already chosen, their bins chosen again with ``prices`` when given
    (:func:`bandelets.quantize.optimise_bins`, as the encoder then codes them), dequantized and
    turned back.
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
                for k, (c, d) in enumerate(zip(local, decoded, strict=True)):
                    b = bandeletize(c[where], trees[i], t1d)
                    q = quantize(b, t)
                    if prices is not None:
                        optimise_bins(b, q, prices[k][where], t, RDOQ_LAMBDA)
                    d[where] = debandeletize(dequantize(q, t), trees[i], t1d)
            frames.rotate(
                decoded, turned[-1], slices[index - 1][0], levels, header.normal_weight, local=False
            )
        level = slices[index][0]
        turned[:] = [frames.level_frames(decoded, level, *args, header.kind)]
        frames.rotate(local, turned[-1], level, levels, header.normal_weight, local=True)

    return local, before


def encode(
    array,
    *,
    bpp: float | None = None,
    threshold: float | None = None,
    psnr: float | None = None,
    max_angle: float | None = None,
    transform: str = "bandelet",
    kind: Kind = "image",
    wavelet: Wavelet | Literal["auto"] = DEFAULT_WAVELET,
    transform_1d: Transform1D = DEFAULT_TRANSFORM_1D,
    depth: int = 0,
    frames: bool = False,
    normal_weight: float = DEFAULT_NORMAL_WEIGHT,
    extension: str = "symmetric",
    restore: bool = True,
    loop_filter: bool = True,
    lifting: bool | None = None,
    progress: bool = False,
    max_memory: int = MAX_MEMORY,
    xy: bool = False,
    max_work: int = MAX_WORK,
    tile: int = 0,
    lossless: bool | None = None,
    riesz: bool | None = None,
) -> bytes:
    """Compress an image, normal map or geometry image into a .bdl file.

    Parameters
    ----------
    array : array_like, shape (H, W) or (H, W, C), C <= 4
        Values as they are (a normal map: vectors in [-1, 1], uint8 / uint16 samples, or
        ``x, y`` alone; a geometry image: positions).
        A normal map whose vectors all lie within :data:`bandelets.normalmaps.ONE_WAY` of +z is
        coded as two channels (:func:`bandelets.normalmaps.equidistant`; ``x, y`` for an ``x, y``
        source); otherwise as three channels, in local frames around the coarser
        decoded normals (:mod:`bandelets.frames`, normal weight
        :data:`bandelets.bitstream.NORMAL_MAP_WEIGHT`).
    bpp, threshold, psnr, max_angle : float, exactly one (none with ``lossless=True``)
        Target rate in bits per pixel (the file lands within 3 % below it, or far below it when
        it is lossless: see ``lossless``), quantization
        threshold ``T``, target PSNR in dB (:func:`bandelets.metrics.psnr` for ``kind``), or
        for a normal map the largest 99th percentile of the angular error in degrees
        (:func:`bandelets.metrics.angular_error`: the mean follows the PSNR, the tail is what
        shows as artefacts along creases; the maximum is one pixel's luck). Quality targets hold
        for the decoded values written at the source's ``depth``.
    transform : {"bandelet", "wavelet"}
        ``"wavelet"`` forces every square to NULL: the same codec without geometry.
    kind : {"image", "normal-map", "geometry-image"}
        A normal map is renormalised to unit vectors before coding and after decoding.
    wavelet : str
        See :data:`bandelets.bitstream.WAVELETS`, or ``"auto"``: encode with each of
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
        Costs no bits; the encoder and decoder then take longer (about 1.6 ms of CPU per
        iteration for 256 x 256 x 2, 6.5 ms for 512 x 512 x 2).
    loop_filter : bool
        Let the decoder filter the (restored) image with a small filter the encoder fits to
        ``array`` and writes into the file (:mod:`bandelets.loopfilter`), where it pays for its
        bytes (a few dozen). Not in tiled files.
    lifting : bool, optional
        Lift the finest :data:`bandelets.directional.LEVELS` wavelet levels along directions
        chosen per block (:mod:`bandelets.directional`; cdf97, not for a geometry image):
        better files on creases at an angle (+0.66 dB BD on the 256 x 256 crease map, +2.63 dB
        at 512, +0.72 dB on fandisk's normal map) in about the same encoding and decoding time.
        None (the default): on for normal maps with cdf97 where the directions pay
        (:func:`bandelets.directional.pays`; else the file is coded without them), off
        otherwise. True: always (an error where it cannot apply); False: never.
    progress : bool
        A progress line on stderr naming the stage (rate control, restoration search).
    max_memory : int
        Refuse (``ValueError``) an image whose encoding would need more than this many bytes.
    xy : bool
        Normal maps: ``array`` holds ``x, y`` and an unused blue (see :mod:`bandelets.normalmaps`,
        which also says how two channels and integer samples are read).
    max_work : int
        Restore for no more iterations than a decoder's ``max_work`` allows
        (:func:`bandelets.memory.check_work`): with the default, the file decodes within the
        default limits of :func:`bandelets.decode`.
    tile : int
        An image with a side above ``tile`` pixels is coded in tiles of about ``tile`` x ``tile``
        (:mod:`bandelets.tiling`: independent tiles at one threshold, two at a time; memory
        bounded whatever the size, a region can be decoded alone), at least
        :data:`~bandelets.tiling.MIN_TILE`. The default, 0, codes in one piece what fits
        ``max_memory`` and in tiles of :data:`~bandelets.tiling.TILE` what does not (tile borders
        can show at low rates: :func:`bandelets.memory.tile_side`).
    lossless : bool, optional
        True: code the integer samples of the source exactly (:mod:`bandelets.lossless`; no
        target): ``uint8`` / ``uint16`` samples of a normal map, or values read from 8 or
        16-bit samples with their ``depth`` (``ValueError`` for anything else); the file decodes
        to the same values, every channel given (``xy`` aside). None (the default): under a
        ``bpp`` target, the lossless file when the source has such samples and that file fits
        the target (smaller than asked, and exact). False: never.
    riesz : bool, optional
        Normal maps coded as two channels: code them as their Riesz pair (:mod:`bandelets.riesz`:
        the channel along the gradients of a height and the one across them), which halves what
        a map baked from a height field costs (+1.4 dB BD on the 256 x 256 bevel map, +4.1 on the
        bumps, +0.7 on the acacia door). None (the default): where the estimate says it pays
        (:data:`RIESZ_PAYS_BELOW`), or under a rate target where it nearly does, both files and
        the better kept (:data:`RIESZ_TRIAL_BELOW`), up to :data:`TRIAL_PIXELS` pixels and with
        cdf97. True: always (a Riesz pair is not lifted along directions); False: never.

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        An unusable image, option or target (an image a default decoder would refuse included).
    TypeError
        A target that is not a real number (``bpp="1"``).

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[0:64, 0:64] / 64
    >>> image = np.tanh(20 * (x - 0.7 * y - 0.2))  # a sharp oblique edge
    >>> data = encode(image, bpp=1.0)
    >>> 8 * len(data) <= image.size  # at most 1 bit per pixel, header included
    True
    """
    options = EncodeOptions(
        transform=transform,
        kind=kind,
        wavelet=wavelet,
        transform_1d=transform_1d,
        depth=depth,
        frames=frames,
        normal_weight=normal_weight,
        extension=extension,
        restore=restore,
        loop_filter=loop_filter,
        lifting=lifting,
        progress=progress,
        max_memory=max_memory,
        xy=xy,
        max_work=max_work,
        tile=tile,
        lossless=lossless,
        riesz=riesz,
    )
    return encode_with_stats(
        array, options, bpp=bpp, threshold=threshold, psnr=psnr, max_angle=max_angle
    ).data


@one_blas_thread()  # the encoder runs threads of its own: BLAS one (bandelets.blasthreads)
def encode_with_stats(
    array,
    options: EncodeOptions,
    *,
    bpp: float | None = None,
    threshold: float | None = None,
    psnr: float | None = None,
    max_angle: float | None = None,
    measured: bool = False,
    unrestored: Encoded | None = None,
) -> Encoded:
    """:func:`encode` with its options already validated, returning also the threshold used, the
    predicted error and (when the encoder chose the restoration, or ``measured``) the PSNR of the
    decoded file at the source's depth and what :func:`decode` returns for it (``measured``
    costs a decode without the restoration).

    ``unrestored``: what this function returned for the same array and options but no restoration,
    at ``threshold``: the file is then only restored and measured, not coded again (a tiled
    encode's last pass, :mod:`bandelets.tiling`)."""
    targets = dict(bpp=bpp, threshold=threshold, psnr=psnr, max_angle=max_angle)
    if options.lossless:
        if any(v is not None for v in targets.values()):
            raise ValueError("a lossless file has no target: give none of bpp, threshold, psnr or max_angle")
        return _lossless(array, options, measured)
    check_targets(options.kind, **targets)
    if options.lossless is None and bpp is not None:
        # A user asking for a rate is given the exact file when it fits: an image of integer
        # samples whose lossless file is no larger than the target is written losslessly (a
        # 2 bpp target met exactly in 1.4 bpp on the lava map: no lossy file of 2 bpp can be
        # better). The lossless coder stops as soon as it passes the target, so trying it costs
        # the share of the image it codes before then (BENCHMARKS, "Lossless files").
        fitted = _lossless(array, options, measured, bpp)
        if fitted is not None:
            return fitted
        options = replace(options, lossless=False)
    if options.wavelet == AUTO_WAVELET:
        return _best_of_wavelets(array, options, measured=measured, **targets)
    if tiling.tiled(array, options):
        return tiling.encode(array, options, measured=measured, **targets)
    kind, max_memory, depth, layout = options.kind, options.max_memory, options.depth, "xyz"
    if kind == "normal-map":
        array, depth, layout = normalmaps.prepare(array, depth, options.xy)
    x = given = check_image(array, kind, max_memory)
    if kind == "normal-map":
        x = metrics.unit_vectors(x)
    levels = max_levels(x.shape[:2])
    geometry = geometry_options(options, x.shape[:2])
    # A map of normals that face one way is coded as two channels: the azimuthal equidistant
    # coordinates of its vectors (see bandelets.normalmaps), or x, y as given (BC5 sources).
    two = kind == "normal-map" and (layout != "xyz" or normalmaps.faces_one_way(x))
    # The normals of a closed surface on an octahedral geometry image (never facing one way).
    folded = kind == "normal-map" and not two and normalmaps.octahedral(x)
    if options.extension == "spherical" or folded:  # no padding: the fold must stay on the image's border
        while levels > 1 and x.shape[0] % (1 << levels):
            levels -= 1
    equidistant = two and layout == "xyz"
    coded = (normalmaps.equidistant(x) if layout == "xyz" else given[..., :2]) if two else x
    # A normal map read from integer samples was converted to floats: that copy is not held.
    del array, given
    if kind == "normal-map":  # three channels: always in local frames
        geometry = implied_options(kind, coded.shape[2])
    coefficients = wavelet_coefficients(coded, options.wavelet, levels, options.extension)
    lifting_levels, lifting = _lifting_levels(options, levels, geometry), None
    # Two channels may be coded as their Riesz pair (turn: the sign of bandelets.riesz.forward, 0 not).
    automatic = (
        options.riesz is None
        and options.lifting is not True
        and options.wavelet == "cdf97"
        and x[..., 0].size <= TRIAL_PIXELS
    )
    pairable = two and (options.riesz or automatic)
    if options.riesz and not two:
        raise ValueError(
            "riesz=True needs a normal map coded as two channels (its vectors within "
            f"{np.degrees(normalmaps.ONE_WAY):.0f} degrees of +z, or x, y alone)"
        )
    turn = 0
    (height, width), channels = x.shape[:2], coded.shape[2]

    def encode_at(t: float, transform: str = options.transform, search=best_trees) -> Encoded:
        header = Header(
            height=height,
            width=width,
            channels=channels,
            kind=kind,
            transform=transform,
            wavelet=options.wavelet,
            levels=levels,
            threshold=max(t, MIN_THRESHOLD),  # rate control's exp(log T) may round below it
            depth=depth,
            transform_1d=options.transform_1d,
            **geometry,
            layout=layout,
            lifting=lifting_levels,
            folded=folded,
            riesz=turn,
        )
        return encode_at_threshold(coefficients, header, lifting, search)

    magnitudes = np.abs(np.concatenate([c.ravel() for c in coefficients]))
    # Above every coefficient, within the thresholds a file may hold: an image of zeros (or of
    # values below MIN_THRESHOLD) is coded at MIN_THRESHOLD, as zeros; values too large for
    # MAX_THRESHOLD are refused by the quantizer.
    t_max = 2.0 * float(magnitudes.max()) * max(1.0, geometry.get("normal_weight", 1.0))
    t_max = min(max(t_max, MIN_THRESHOLD), MAX_THRESHOLD)
    # A rate target's model keeps a sample of the magnitudes, not all of them.
    model = ratecontrol.size_model(magnitudes) if bpp is not None else None
    del magnitudes
    reference = x[..., 0] if x.shape[2] == 1 else x[..., :2] if layout == "xy" else x
    # A quality target's search starts where a uniform quantizer's error would meet it.
    t_guess = None
    if max_angle is not None:
        t_guess = min(t_max, np.radians(max_angle))
    elif psnr is not None:
        t_guess = min(t_max, 2.0 * metrics.peak(reference, kind) * 10 ** (-psnr / 20)) or t_max / 1e3
    # Fewer levels where the median predictor codes the coarse band for less (levelchoice), at
    # the threshold expected: the first of rate control or of a quality target's search.
    targeted = (bpp, threshold, t_guess) != (None,) * 3
    choosing = kind == "normal-map" and options.wavelet == "cdf97" and targeted
    level_trial = []  # the runner-up count of levels, if close, for a rate target to try
    if choosing:
        t = t_guess
        if threshold is not None:
            t = float(threshold)
        elif bpp is not None:
            t = ratecontrol.first_threshold(int(bpp * height * width / 8), t_max, model)
        fewer, *level_trial = levels_to_try(coefficients, levels, t, frames=not two)
        if fewer < levels:
            levels, lifting_levels = fewer, _lifting_levels(options, fewer, geometry)
            coefficients = wavelet_coefficients(coded, options.wavelet, levels, options.extension)
            if model is not None:
                model = ratecontrol.size_model(np.abs(np.concatenate([c.ravel() for c in coefficients])))
    del x
    measure_channels = targets = to_error = None
    # Bytes the loop filter may take: a rate target keeps some aside (None: no limit).
    filter_budget = None
    # The decoded image is kept for the caller (measured) or the angular target.
    keep = measured or max_angle is not None
    # A copy of the reference, made when first needed (not by a rate target with the restoration).
    measure_psnr = None
    # The other files a rate target tries, the better kept: the coefficients, directions, levels
    # lifted and Riesz sign of each (the lifted ones, see TRIAL_BELOW; the Riesz pair, RIESZ_TRIAL_BELOW;
    # a count of levels close to the one chosen, levelchoice.TRY_WITHIN).
    trials = []

    def measure(decoded: np.ndarray) -> float:
        nonlocal measure_psnr
        if measure_psnr is None:
            measure_psnr = metrics.psnr_against(reference, kind)
        return measure_psnr(as_read(decoded, kind, depth))

    def prepare(t: float | None, tries: bool = False) -> None:
        """Before rate control: lift along directions chosen for ``t`` (None: no lifting) where
        they pay (:func:`_lifted`; ``tries``: keep the lifted coefficients to try where they
        nearly pay), make the restoration's measure, and let go of the source where it is not
        measured again (one large array at a time: the peak of large images)."""
        nonlocal coefficients, lifting, lifting_levels, coded, reference, measure_channels, targets, to_error
        nonlocal turn, t_max, levels
        tries = tries and height * width <= TRIAL_PIXELS
        if lifting_levels and t is not None:
            coefficients, lifting, lifting_levels, trial = _lifted(
                coded, coefficients, levels, lifting_levels, t, options.lifting is None
            )
            if trial is not None and tries:
                trials.append((*trial, 0, levels))
        if level_trial and tries:
            trials.append((*_with_levels(coded, level_trial[0], t, options, geometry), 0, level_trial[0]))
        if pairable and t is not None:
            sign, pair, paired_levels, ratio = _riesz_pair(
                coded, coefficients, lifting, lifting_levels, levels, t, options, choose=choosing
            )
            if ratio < RIESZ_PAYS_BELOW:
                coefficients, lifting, lifting_levels, turn, levels = pair, None, 0, sign, paired_levels
                trials.clear()
                t_max = _above(pair, t_max)
            elif ratio < RIESZ_TRIAL_BELOW and tries:
                trials.append((pair, None, 0, sign, paired_levels))
            del pair
        coded = None
        if options.restore or options.loop_filter:  # what the user gets: the values written at its depth
            measure_channels = metrics.psnr_of_channels(reference, kind, depth, equidistant)
        if options.loop_filter:  # what the coded channels stand for, and the error of a PSNR
            planes = (
                normalmaps.equidistant(reference) if equidistant else reference.reshape(height, width, -1)
            )
            targets = np.ascontiguousarray(np.moveaxis(planes[..., :channels], -1, 0), np.float32)
            to_error = partial(
                _squared_error,
                peak=metrics.peak(reference, kind),
                samples=height * width * (3 if kind == "normal-map" else channels),
            )
        # Rate control holds the source only where it measures a decoded image against it: a
        # quality target, or a measured encode without the restoration.
        if not (psnr is not None or max_angle is not None or (measured and not options.restore)):
            reference = None

    def decoded(encoded: Encoded) -> np.ndarray:
        if encoded.decoded is not None:  # the restored image, as decode returns it
            return encoded.decoded
        # Our own file: only the caller's memory limit applies, not the limits on foreign files.
        return decode(
            encoded.data, max_memory=max_memory, max_work=options.max_work, max_side=2**32, max_samples=2**64
        )

    with Progress(options.progress) as line:

        def finished(encoded: Encoded) -> Encoded:
            if options.restore or options.loop_filter:
                encoded, channels = _with_restoration(
                    encoded, measure_channels, options, line, keep and not options.loop_filter
                )
                if options.loop_filter:
                    budget = None if filter_budget is None else filter_budget - len(encoded.data)
                    encoded = _with_loop_filter(
                        encoded, channels, targets, measure_channels, to_error, budget, keep
                    )
            elif measured:
                out = decoded(encoded)
                encoded = replace(encoded, psnr=measure(out), decoded=out)
            # Only the restoration's choice needed the trees and bins; the decoded image is kept
            # for the caller (measured) or the angular target, not held through rate control.
            return replace(
                encoded, trees=None, bins=None, lifting=None, decoded=encoded.decoded if keep else None
            )

        if unrestored is not None:
            prepare(None)
            return finished(_read_back(unrestored))
        if threshold is not None:
            prepare(float(threshold))
            return finished(encode_at(float(threshold)))
        line.stage("rate control")
        if bpp is not None:
            target = int(bpp * height * width / 8)
            if target < HEADER_BYTES:
                raise ValueError(
                    f"target of {bpp:g} bpp ({target} bytes) cannot be reached: a .bdl file needs at "
                    f"least {HEADER_BYTES} bytes of header"
                )
            # Room is left for the loop filter's bytes (what the file does not take of it is lost).
            room = loopfilter.reserve(channels) if options.loop_filter else 0
            filter_budget = target
            aimed = lifting_levels or pairable
            first = ratecontrol.first_threshold(target - room, t_max, model) if aimed else None
            prepare(first, tries=options.restore or options.loop_filter)

            def lifted_model():
                # The size of a lifted file follows a model of the lifted coefficients better (the
                # pair codes' flat blocks): as many encodings as before them, not one more at 0.7 to
                # 2 bpp on the crease maps. A regular sample (odd step) keeps the sort short.
                lifted = np.concatenate([c.ravel() for c in coefficients])
                return ratecontrol.size_model(np.abs(lifted[::3]), lifted.size)

            def reusing():
                # The loop's later encodes reuse the geometry of its first (bandelets.treememo).
                return partial(encode_at, search=TreeMemo().search)

            # A wavelet file aims the first encoding (none where it would be the file itself).
            probe = None if options.transform == "wavelet" else partial(_probe, encode_at, bpp)
            if lifting is not None or turn:
                model = lifted_model()
            kept = finished(
                ratecontrol.for_size(reusing(), target, t_max, model, line, MIN_THRESHOLD, room, probe)
            )
            while trials and kept.psnr is not None:
                # Directions or a Riesz pair close to paying: that file too, the better kept.
                coefficients, lifting, lifting_levels, turn, levels = trials.pop(0)
                if turn:
                    t_max = _above(coefficients, t_max)
                model = lifted_model()
                other = finished(
                    ratecontrol.for_size(reusing(), target, t_max, model, line, MIN_THRESHOLD, room, probe)
                )
                kept = other if other.psnr > kept.psnr else kept
            return kept
        if max_angle is not None:
            # -20 log10 of the angle falls with log T like a PSNR: the same search applies.
            goal = -20.0 * np.log10(max_angle)

            def quality(encoded: Encoded) -> float:
                p99 = metrics.angular_error(reference, as_read(decoded(encoded), kind, depth)).p99
                return -20.0 * np.log10(max(p99, 1e-12))

            def label(q: float) -> str:
                return f"p99 angle of {10 ** (-q / 20):.3g} degrees"
        else:
            goal = float(psnr)

            def quality(encoded: Encoded) -> float:
                return encoded.psnr if encoded.psnr is not None else measure(decoded(encoded))

            def label(q: float) -> str:
                return f"PSNR of {q:.2f} dB"

        prepare(t_guess)
        # Each try is restored: the target is met by the restored image, with the smallest file.
        return ratecontrol.for_quality(
            lambda t: finished(encode_at(t)), quality, goal, t_max, t_guess, line, label, MIN_THRESHOLD
        )


#: A rate target's first file is encoded where a wavelet file, priced as the bandelet file at
#: ``exp(PROBE_BIAS / bpp)`` times its size, meets the target (:func:`bandelets.ratecontrol.for_size`):
#: the median of that ratio over the maps of issue 15 at 0.25 to 2 bpp (1.005 to 1.036 at 1 bpp).
PROBE_BIAS = 0.016


def _probe(encode_at, bpp: float, t: float) -> float:
    """The size of the file ``encode_at`` makes at ``t`` predicted from that of the wavelet file
    (every square NULL: 0.13 to 0.2 of the time of the bandelet file at 256 and 512 pixels a side,
    slightly smaller; see :data:`PROBE_BIAS`)."""
    return len(encode_at(t, "wavelet").data) * math.exp(PROBE_BIAS / bpp)


def _lossless(array, options: EncodeOptions, measured: bool, bpp: float | None = None) -> Encoded | None:
    """The lossless file of ``array`` (:mod:`bandelets.lossless`): with ``bpp``, None when
    ``array`` has no integer samples or the file would be larger than ``bpp``; without,
    ``ValueError`` when ``array`` has no integer samples. ``measured``: the file is decoded and
    compared with the samples (PSNR infinite)."""
    shape = np.shape(array)
    if bpp is not None and len(shape) in (2, 3):
        try:  # the lossless coder works in one piece: an image that needs tiles is coded lossy
            check_encodable(*shape[:2], shape[2] if len(shape) == 3 else 1, options.max_memory, tile=0)
        except ValueError:
            return None
    found = lossless.samples_of(array, options.kind, options.depth)
    if found is None:
        if bpp is not None:
            return None
        array = np.asarray(array)
        check_image(
            normalmaps.prepare(array, options.depth, False)[0] if options.kind == "normal-map" else array,
            options.kind,
            options.max_memory,
        )
        raise ValueError(
            "lossless coding needs integer samples: an 8 or 16-bit PNG or TIFF, uint8 / uint16 samples of "
            "a normal map, or values read from such samples with their depth"
        )
    samples, depth = found
    height, width, channels = samples.shape
    check_encodable(height, width, channels, options.max_memory, tile=0)
    budget = None if bpp is None else int(bpp * height * width / 8)
    data = lossless.encode_file(samples, options.kind, depth, budget)
    if data is None:
        return None
    header = unpack(data, max_side=2**32, max_samples=2**64)[0]
    decoded = None
    if measured:
        decoded = decode(data, max_memory=options.max_memory, max_side=2**32, max_samples=2**64)
        if not np.array_equal(
            to_samples(decoded, options.kind, depth), samples[..., 0] if channels == 1 else samples
        ):
            raise RuntimeError("the lossless file does not decode to its source: please report this bug")
    return Encoded(data, 1.0, 0.0, psnr=float("inf"), decoded=decoded, header=header)


def _read_back(encoded: Encoded) -> Encoded:
    """``encoded`` with the header, quadtrees, bins and directions its file holds, as the decoder
    reads them, and without its loop filter (fitted to the unrestored image: chosen again)."""
    header, streams = unpack(encoded.data, max_side=2**32, max_samples=2**64)
    trees, bins, lifting = decoded_bins(header, streams)
    header = replace(header, loop_filter=None)
    data = pack(header, streams)
    return replace(encoded, data=data, header=header, trees=trees, bins=bins, lifting=lifting)


#: Where :func:`bandelets.directional.pays` says the directions do not pay but their cost ratio
#: (:func:`bandelets.directional.cost_ratio`) is below this, a rate target tries both files and
#: keeps the better: the estimate's threshold is a compromise that the objects' normal maps
#: rendered from meshes cross (ratios of 0.89 to 0.95 at 256 and 512, where the lifted file
#: gains 0.1 to 2.6 dB; the crease map at 256 and low rates, 0.89 to 0.91, loses 0.1 to 0.4 dB).
#: The smooth maps (bumps, lava flow: 1.00 to 1.01) are not tried.
TRIAL_BELOW = 0.96
#: Largest image (pixels) tried both ways: the trial holds a second set of coefficients.
TRIAL_PIXELS = 1024 * 1024


def _lifted(
    coded: np.ndarray, plain: list, levels: int, lifting_levels: int, threshold: float, check: bool
) -> tuple[list, list | None, int, tuple | None]:
    """The coefficients of the (padded) channels of ``coded`` lifted along directions, the
    directions, chosen for ``threshold`` (:func:`bandelets.directional.lift`: slopes and pair
    codes), the levels lifted and None; or, with ``check``, where the directions do not pay
    (:func:`bandelets.directional.pays`), the plain coefficients ``plain``, None, 0 and, when
    their cost ratio is below :data:`TRIAL_BELOW`, the lifted ones, directions and levels (to try)."""
    channels = padded_channels(coded, levels)
    lifted, fields, lifting_levels, cost = directional.lift(channels, levels, lifting_levels, threshold)
    frames = len(channels) == 3  # a normal map's three channels are coded in local frames
    if not check or directional.pays(
        channels, lifted, fields, levels, lifting_levels, threshold, frames, plain, cost
    ):
        return lifted, fields, lifting_levels, None
    close = directional.cost_ratio(channels, lifted, fields, levels, lifting_levels, threshold, plain, cost)
    return plain, None, 0, (lifted, fields, lifting_levels) if close < TRIAL_BELOW else None


def _with_levels(
    coded: np.ndarray, levels: int, threshold: float | None, options: EncodeOptions, geometry: dict
) -> tuple[list, list | None, int]:
    """The coefficients of the channels ``coded`` with ``levels`` wavelet levels, lifted along
    directions chosen for ``threshold`` where they pay (none without a threshold), the directions
    and the levels lifted: a count of levels to try (:func:`bandelets.levelchoice.levels_to_try`)."""
    coefficients = wavelet_coefficients(coded, options.wavelet, levels, options.extension)
    lifting_levels = _lifting_levels(options, levels, geometry)
    if not lifting_levels or threshold is None:
        return coefficients, None, 0
    return _lifted(coded, coefficients, levels, lifting_levels, threshold, options.lifting is None)[:3]


#: Where the Riesz pair's :func:`bandelets.directional.cost` over that of the channels (lifted or
#: not) is below this, the pair is coded (:func:`_riesz_pair`); where it is below
#: :data:`RIESZ_TRIAL_BELOW`, a rate target encodes both files and keeps the better (else the
#: channels). The estimate misses much of what the context coder makes of a pair: of the files of
#: the maps of issue 15 at 0.25 to 2 bpp (``benchmarks/riesz_choice.py``; BENCHMARKS, "Where main
#: stands: format version 15"), those at a ratio of 0.91 or less gained +0.7 to +4.2 dB with it
#: (bevel, bumps, acacia door) but one (the acacia door at 0.25 bpp: 0.88, -0.14 dB); between 0.93
#: and 1.5 some gained up to 1.8 dB (bevel, bumps, acacia door, crease at 0.25 bpp, 1.50 at 512)
#: and others lost up to 1.7 dB (bunny from the top at 0.35 and 0.5 bpp: 0.99 and 1.08); above 1.5
#: only losses (0.3 to 24 dB: lava flow, fandisk from the top, crease from 1 bpp).
RIESZ_PAYS_BELOW = 0.9
RIESZ_TRIAL_BELOW = 1.6
#: Where the smaller curl (:func:`bandelets.riesz.oriented`) still holds more than this share of the
#: energy, the map is no height field, and the sign of the pair is the one whose cost estimate is
#: lower: on the acacia door (26 % of curl with the smaller-curl sign) the other sign's estimate is
#: lower and its files better by 0.05 to 0.86 dB at 0.5 to 2 bpp (+0.27 dB BD).
RIESZ_SIGN_BY_COST = 0.05


def _riesz_pair(
    coded: np.ndarray,
    coefficients: list,
    lifting,
    lifted: int,
    levels: int,
    threshold: float,
    options: EncodeOptions,
    choose: bool,
) -> tuple[int, list, int, float]:
    """The Riesz sign and the pair's coefficients of the channels ``coded`` (:func:`bandelets.riesz.oriented`,
    padded), its wavelet levels, and the ratio of their :func:`bandelets.directional.cost` at
    ``threshold`` over that of the channels' ``coefficients`` (``levels`` levels, ``lifted`` of them
    lifted with the directions ``lifting``, if any); 0 with ``options.riesz``. With ``choose``, the
    pair's levels are chosen again (:func:`bandelets.levelchoice.choose_levels`): its coarse band is
    not the channels' (the bevel map at 256 kept 2 levels of 5 for its channels; its pair lost 0.28
    dB at 0.25 bpp with them, gained 0.16 at 2 bpp)."""

    def plain_cost(samples, transformed, count):  # unlifted: the directions' side costs zeros
        return directional.cost(samples, transformed, None, count, min(directional.LEVELS, count), threshold)

    top = max_levels(coded.shape[:2]) if choose else levels
    channels = padded_channels(coded, top)
    sign, *pair = riesz.oriented(*channels)
    turned = [wavedec(c, options.wavelet, top) for c in pair]
    energy = [float(np.sum(c * c)) for c in pair]
    if energy[1] > RIESZ_SIGN_BY_COST * sum(energy):  # no height field: the cheaper sign
        other = riesz.forward(*channels, -sign)
        flipped = [wavedec(c, options.wavelet, top) for c in other]
        if plain_cost(other, flipped, top) < plain_cost(pair, turned, top):
            sign, pair, turned = -sign, other, flipped
        del other, flipped
    if choose and (fewer := choose_levels(turned, top, threshold)) < top:
        top, channels = fewer, padded_channels(coded, fewer)
        pair = riesz.forward(*channels, sign)
        turned = [wavedec(c, options.wavelet, top) for c in pair]
    if options.riesz:
        return sign, turned, top, 0.0
    channels = padded_channels(coded, levels)
    if lifting is None:
        now = plain_cost(channels, coefficients, levels)
    else:
        now = directional.cost(channels, coefficients, lifting, levels, lifted, threshold)
    return sign, turned, top, plain_cost(pair, turned, top) / now if now > 0 else 1.0


def _above(coefficients: list, t_max: float) -> float:
    """``t_max`` raised to twice the largest of ``coefficients`` (a Riesz pair gathers the energy
    of two channels into one), within :data:`bandelets.bitstream.MAX_THRESHOLD`."""
    return min(max(t_max, 2.0 * max(float(np.abs(c).max()) for c in coefficients)), MAX_THRESHOLD)


def _lifting_levels(options: EncodeOptions, levels: int, geometry: dict) -> int:
    """Wavelet levels to lift along directions for ``options.lifting`` (see :func:`encode`)."""
    if options.lifting is None:  # the default: normal maps with CDF 9/7
        wanted = options.kind == "normal-map" and options.wavelet == "cdf97"
    else:
        wanted = options.lifting
    return min(directional.LEVELS, levels) if wanted else 0


#: The encoder stops trying more restoration iterations this many after the best so far.
_RESTORATION_PATIENCE = 10
#: Of the restoration's gain in PSNR over plain dequantization, the share the count written into
#: the file keeps: the fewest iterations that reach it, not the best (the PSNR flattens out near
#: the best: on the 512 x 512 crease map at 1 bpp 39 iterations instead of 45 keep 97 % of 5.9 dB,
#: and decode 13 % faster).
RESTORATION_SHARE = 0.97


def _squared_error(psnr: float, peak: float, samples: int) -> float:
    """The summed squared error of ``samples`` values that a PSNR of ``psnr`` dB stands for."""
    return 0.0 if psnr == float("inf") else samples * peak**2 * 10.0 ** (-psnr / 10.0)


#: Copies of the restored channels the encoder keeps while it searches, so that the channels of
#: the count chosen need not be made again (for the loop filter): at most _KEPT, of at most
#: _KEPT_BYTES together (none of a 2048 x 2048 map: made again, the encoder's peak memory stays).
_KEPT, _KEPT_BYTES = 3, 16 * 2**20


def _with_restoration(
    encoded: Encoded, measure, options: EncodeOptions, line: Progress, keep: bool
) -> tuple[Encoded, np.ndarray]:
    """``encoded`` with the fewest restoration iterations whose decoded channels keep
    :data:`RESTORATION_SHARE` of the best gain in score by ``measure``
    (:func:`bandelets.metrics.psnr_of_channels`) written into its header (at most as many as
    ``options.max_work`` allows a decoder; none without ``options.restore``), that score and
    (``keep``) that decoded image; and the decoded channels (C, H', W')."""
    header = encoded.header
    most = 0
    if options.restore:
        try:
            check_memory(replace(header, restoration=1), options.max_memory)
            most = min(MAX_RESTORATION, options.max_work // restoration_work(replace(header, restoration=1)))
        except FormatError:  # the decoder could not afford it either
            pass
    scores: list[float] = []
    # Copies of the channels of the iterations that may be chosen (at most _KEPT_BYTES): the one
    # chosen is then not made again.
    kept: dict[int, np.ndarray] = {}
    line.stage("restoration search", restart=True)
    for n, channels in enumerate(restorations(header, encoded.trees, encoded.bins, encoded.lifting)):
        scores.append(measure(channels))
        line.step(f"T={header.threshold:.3g}: {scores[-1]:.2f} dB")
        if n >= most or n - int(np.argmax(scores)) >= _RESTORATION_PATIENCE:
            break
        # Only the iterations that keep the share of the best gain so far can be the one chosen
        # (the share of the final best is larger): copies of those, the earliest first.
        share = scores[0] + RESTORATION_SHARE * (max(scores) - scores[0])
        kept = {k: c for k, c in kept.items() if scores[k] >= share}
        if scores[n] >= share and len(kept) < _KEPT and (len(kept) + 1) * channels.nbytes <= _KEPT_BYTES:
            kept[n] = channels.copy()
    line.stage("rate control")
    best = int(np.argmax(scores))
    if best > 0:  # the fewest iterations that keep the share (the plain decoding if no gain)
        best = next(
            n for n, s in enumerate(scores) if s - scores[0] >= RESTORATION_SHARE * (scores[best] - scores[0])
        )
    if best in kept:
        channels = kept[best]
    elif best != len(scores) - 1:  # the iterations work in place: made again up to the count chosen
        channels = next(
            islice(restorations(header, encoded.trees, encoded.bins, encoded.lifting), best, None)
        )
    output = decoded_image(channels, header) if keep else None
    if best == 0:
        return replace(encoded, psnr=scores[0], decoded=output), channels
    header, streams = unpack(encoded.data, max_side=2**32, max_samples=2**64)
    data = pack(replace(header, restoration=best), streams)
    return replace(encoded, data=data, psnr=scores[best], decoded=output), channels


def _with_loop_filter(
    encoded: Encoded, channels: np.ndarray, targets: np.ndarray, measure, to_error, budget, keep: bool
) -> Encoded:
    """``encoded`` with the loop filter :func:`bandelets.loopfilter.choose` finds for its decoded
    ``channels`` against ``targets`` (none if none pays; at most ``budget`` bytes), its score by
    ``measure`` and (``keep``) its decoded image; ``to_error``: a score to the squared error."""
    header = encoded.header
    found, filtered = loopfilter.choose(
        channels, targets, header.threshold, LAMBDA, lambda c: to_error(measure(c)), budget, header.folded
    )
    if found is None:
        return replace(encoded, decoded=decoded_image(channels, header) if keep else None)
    header, streams = unpack(encoded.data, max_side=2**32, max_samples=2**64)
    data = pack(replace(header, loop_filter=found), streams)
    output = decoded_image(filtered, header) if keep else None
    return replace(encoded, data=data, psnr=measure(filtered), decoded=output)


#: CDF 9/7 is best on smooth content; Haar on piecewise-constant content (the facets of a CAD
#: normal map) once the rate is high enough to code the creases exactly.
AUTO_CANDIDATES = ("cdf97", "haar")


def _best_of_wavelets(array, options: EncodeOptions, *, bpp, measured, **targets) -> Encoded:
    """Encode with each wavelet of :data:`AUTO_CANDIDATES` and keep the best file.

    For a rate target, the one whose decoded image has the higher PSNR; for a quality target
    the smaller file; at a fixed threshold the smaller ``error + LAMBDA T**2 bits``.
    """
    # The spherical extension exists for CDF 9/7 only.
    candidates = AUTO_CANDIDATES if options.extension == "symmetric" else ("cdf97",)
    files = [
        # A rate target compares the PSNR of each.
        encode_with_stats(
            array,
            replace(options, wavelet=w, lifting=options.lifting if w == "cdf97" else False, lossless=False),
            bpp=bpp,
            measured=measured or bpp is not None,
            **targets,
        )
        for w in candidates
    ]
    if targets["threshold"] is not None:
        return min(files, key=lambda f: f.coefficient_sse + LAMBDA * f.threshold**2 * 8 * len(f.data))
    if bpp is None:
        return min(files, key=lambda f: len(f.data))
    return max(files, key=lambda f: f.psnr)
