"""Encoding of .bdl files, the front door: ``encode(array, ...) -> bytes``.

:func:`encode_with_stats` sends an image where it is coded: the lossless coder where the source's
integer samples fit the target (:mod:`bandelets.coding.lossless`), both candidate wavelets of
``wavelet="auto"``, tiles for a large image (:mod:`bandelets.codec.tile_encoder`), else one piece
(:mod:`bandelets.codec.piece`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..coding import lossless
from ..format.checks import check_image, check_targets
from ..format.fields import Kind
from ..format.header import unpack
from ..format.limits import OWN_FILE, check_encodable
from ..format.samples import to_samples
from ..runtime.blas import one_blas_thread
from ..search.lagrangian import LAMBDA
from . import hardsurface, normalmaps, tile_encoder, variants
from .at_threshold import Encoded
from .decoder import decode
from .options import AUTO_WAVELET, GEOMETRY_FROM, LOOP_FILTER_FROM, EncodeOptions
from .piece import encode_piece

__all__ = ["AUTO_CANDIDATES", "Encoded", "encode", "encode_with_stats"]


def encode(
    array,
    *,
    bpp: float | None = None,
    threshold: float | None = None,
    psnr: float | None = None,
    max_angle: float | None = None,
    options: EncodeOptions | None = None,
    **overrides,
) -> bytes:
    """Compress an image, normal map or geometry image into a .bdl file.

    Parameters
    ----------
    array : array_like, shape (H, W) or (H, W, C), C <= 4
        Values as they are (a normal map: vectors in [-1, 1], uint8 / uint16 samples, or
        ``x, y`` alone; a geometry image: positions).
        A normal map whose vectors all lie within :data:`bandelets.codec.normalmaps.ONE_WAY` of +z is
        coded as two channels (:func:`bandelets.codec.normalmaps.equidistant`; ``x, y`` for an ``x, y``
        source); otherwise as three channels, in local frames around the coarser
        decoded normals (:mod:`bandelets.transform.frames`, normal weight
        :data:`bandelets.format.header.NORMAL_MAP_WEIGHT`).
    bpp, threshold, psnr, max_angle : float, exactly one (none with ``lossless=True``)
        Target rate in bits per pixel (the file lands within 3 % below it, or far below it when
        it is lossless: see ``lossless``), quantization
        threshold ``T``, target PSNR in dB (:func:`bandelets.metrics.psnr` for ``kind``), or
        for a normal map the largest 99th percentile of the angular error in degrees
        (:func:`bandelets.metrics.angular_error`: the mean follows the PSNR, the tail is what
        shows as artefacts along creases; the maximum is one pixel's luck). Quality targets hold
        for the decoded values written at the source's ``depth``.
    options : EncodeOptions, optional
        How to encode (every choice but the target; :class:`bandelets.codec.options.EncodeOptions`
        documents each), the defaults if None.
    **overrides
        Any field of :class:`~bandelets.codec.options.EncodeOptions` by keyword (``kind="normal-map"``),
        over ``options``.

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
    options = EncodeOptions(**overrides) if options is None else replace(options, **overrides)
    return encode_with_stats(
        array, options, bpp=bpp, threshold=threshold, psnr=psnr, max_angle=max_angle
    ).data


@one_blas_thread()  # the encoder runs threads of its own: BLAS one (bandelets.runtime.blas)
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
    decoded file at the source's depth and what :func:`bandelets.decode` returns for it
    (``measured`` costs a decode without the restoration).

    ``unrestored``: what this function returned for the same array and options but no restoration,
    at ``threshold``: the file is then only restored and measured, not coded again (a tiled
    encode's last pass, :mod:`bandelets.codec.tile_encoder`)."""
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
    if options.effort < LOOP_FILTER_FROM:
        options = replace(options, loop_filter=False)
    if options.wavelet == AUTO_WAVELET:
        return _best_of_wavelets(array, options, measured=measured, **targets)
    tiled = tile_encoder.tiled(array, options)
    if unrestored is None and variants.applies(options, tiled):  # effort 9: the hard-surface choices too
        return variants.best_of_variants(array, options, encode_with_stats, measured=measured, **targets)
    guessed = hardsurface.with_guess(np.asarray(array), options, tiled)  # below effort 9: the guess of it
    if guessed is options and options.effort < GEOMETRY_FROM and options.transform == "bandelet":
        guessed = replace(options, transform="wavelet")  # the fast efforts: no geometry search
    options = guessed
    if tiled:
        return tile_encoder.encode_tiles(array, options, measured=measured, **targets)
    return encode_piece(array, options, measured=measured, unrestored=unrestored, **targets)


#: A rate target tries the lossless file unless its estimated size passes the target this many times.
LOSSLESS_MARGIN = 1.5


def _lossless(array, options: EncodeOptions, measured: bool, bpp: float | None = None) -> Encoded | None:
    """The lossless file of ``array`` (:mod:`bandelets.coding.lossless`): with ``bpp``, None when
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
            normalmaps.prepare(array, options.depth, False)[0] if options.kind == Kind.NORMAL_MAP else array,
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
    normals = options.kind == Kind.NORMAL_MAP
    # Most rate targets are far below the lossless file: an estimate from an eighth of the rows
    # (off by -4 to +14 % on the shared maps) spares coding half the image twice to find out.
    if budget is not None and lossless.estimated_bytes(samples, depth, normals) > LOSSLESS_MARGIN * budget:
        return None
    data = lossless.encode_file(samples, options.kind, depth, budget)
    if data is None:
        return None
    header = unpack(data, **OWN_FILE)[0]
    decoded = None
    if measured:
        decoded = decode(data, max_memory=options.max_memory, **OWN_FILE)
        if not np.array_equal(
            to_samples(decoded, options.kind, depth), samples[..., 0] if channels == 1 else samples
        ):
            raise RuntimeError("the lossless file does not decode to its source: please report this bug")
    return Encoded(data, 1.0, 0.0, psnr=float("inf"), decoded=decoded, header=header)


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
