"""The highest effort's trial of the choices that hard-surface normal maps want (issue 37).

A normal map of bevelled plates and slats (the shared vent decal) codes better with the paper's
Haar along the bandelet directions than with the default Alpert transform, and with the finest
levels lifted along directions even where the estimate of
:func:`bandelets.transform.directional.pays` says they do not pay: both at once gained +1.18 dB
BD-PSNR over the defaults on the vent decal at 0.25 to 1 bpp (BENCHMARKS.md, "Hard-surface
normal maps"). Neither is a good guess on every map, and no estimate was found that tells them
apart in the time, so at :data:`VARIANTS_FROM` the encoder codes the map with each of
:data:`VARIANTS` and keeps the better file, as ``wavelet="auto"`` does with the wavelets
(:func:`bandelets.codec.encoder._best_of_wavelets`): the file format is the same, only the
encoder's time grows (about ``len(VARIANTS)`` times). Below that effort the variant is coded alone
where the map's runs of equal samples lie along one axis only (:mod:`bandelets.codec.hardsurface`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..format.fields import DEFAULT_TRANSFORM_1D, DEFAULT_WAVELET, Kind
from ..search.lagrangian import LAMBDA
from .at_threshold import Encoded
from .options import EncodeOptions

__all__ = ["VARIANTS", "VARIANTS_FROM", "applies", "best_of_variants"]

#: The effort from which :func:`best_of_variants` is used.
VARIANTS_FROM = 9
#: The options tried beside the ones given (the first, ``{}``): Haar along the directions with the
#: directions forced (+1.18 dB BD on the vent decal, where each alone gave +0.58 and +0.52).
VARIANTS: tuple[dict, ...] = ({}, {"transform_1d": "haar", "lifting": True})


def applies(options: EncodeOptions, tiled: bool) -> bool:
    """Whether :func:`best_of_variants` codes an image with ``options`` (``tiled``: in tiles).

    Normal maps in one piece, with the default wavelet and bandelets, at :data:`VARIANTS_FROM`,
    where the user left the 1D transform at its default and the lifting to the encoder.
    """
    return (
        options.effort >= VARIANTS_FROM
        and options.kind == Kind.NORMAL_MAP
        and options.wavelet == DEFAULT_WAVELET
        and options.transform == "bandelet"
        and options.transform_1d == DEFAULT_TRANSFORM_1D
        and options.lifting is None
        and not tiled
    )


def best_of_variants(
    array: np.ndarray,
    options: EncodeOptions,
    encode: Callable[..., Encoded],
    *,
    bpp: float | None,
    measured: bool,
    **targets,
) -> Encoded:
    """Encode ``array`` with ``options`` changed by each of :data:`VARIANTS` and keep the best file.

    Parameters
    ----------
    array : ndarray
        The image, as :func:`bandelets.codec.encoder.encode_with_stats` takes it.
    options : EncodeOptions
        The options (:func:`applies` true of them); each variant is coded one effort below
        :data:`VARIANTS_FROM`, which tries no variants.
    encode : callable
        :func:`bandelets.codec.encoder.encode_with_stats` (passed in: this module is below it).
    bpp : float or None
        The rate target, if any.
    measured : bool
        Whether the returned file must carry its decoded image and PSNR.
    **targets
        The other targets (``threshold``, ``psnr``, ``max_angle``), as ``encode`` takes them.

    Returns
    -------
    Encoded
        For a rate target the file whose decoded image has the higher PSNR; for a quality target
        the smaller file; at a fixed threshold the smaller ``error + LAMBDA T**2 bits``.
    """
    below = replace(options, effort=VARIANTS_FROM - 1)
    files = [
        encode(array, replace(below, **variant), bpp=bpp, measured=measured or bpp is not None, **targets)
        for variant in VARIANTS
    ]
    if targets.get("threshold") is not None:
        return min(files, key=lambda f: f.coefficient_sse + LAMBDA * f.threshold**2 * 8 * len(f.data))
    if bpp is None:
        return min(files, key=lambda f: len(f.data))
    return max(files, key=lambda f: f.psnr)
