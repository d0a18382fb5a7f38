"""How many wavelet levels a normal map is coded with: the encoder's choice, at the threshold it
expects (format unchanged: the header holds the levels).

The coarse approximation is coded as the residual of the median predictor of LOCO-I
(:func:`bandelets.coding.coefficients.code_coefficients`), an intra prediction in all but name. On
piecewise-flat maps (facets, flat backgrounds, bevels with a flat top) that prediction codes a
coarse approximation for less than the CDF 9/7 levels that would split it further, whose long
synthesis functions also spread each edge's quantization error far around it: stopping at 2
levels gained +1.76 dB BD-PSNR on the fandisk rendered from the top and +0.62 on the bevel map at
256, while the smooth bumps map lost 2.7 dB (BENCHMARKS, "Fewer levels where the median predictor
codes the coarse band for less"). So the encoder tries the counts of :data:`CANDIDATES` against
all the levels, on the part of the image they differ on: the approximation of :data:`MIN_LEVELS`
levels, coded as it is, or split by further levels as the codec would code it
(:func:`bandelets.transform.wavelets.coarse_blocks`); each priced by the coefficient coder itself (its ideal
code length) and the quantization error, ``error + LAMBDA T**2 bits``, and the cheapest kept
where it saves enough (:data:`PAYS_BELOW`). That part is a sixteenth of the image: about 20 ms at
512 x 512, 2 % of an encoding.

A normal map of three channels (in local frames, :mod:`bandelets.transform.frames`) is priced the same way,
on its coefficients in the global frame, but keeps fewer levels only at :data:`FRAMES_LEVELS` and
under the stricter :data:`FRAMES_PAY_BELOW`: its details are coded in frames that the estimate does
not see. On fandisk's normal map at 256, three levels of five gained +0.17 to +0.24 dB at 0.25 to
2 bpp (estimate 0.945 to 0.956 of all the levels' cost), two lost up to 2.2 dB; on bunny's, three
lost up to 0.46 dB (estimate 0.987 to 0.994): +0.22 dB BD-PSNR on fandisk's, bunny's unchanged
(``benchmarks/rd_defaults.py``).

The prices code the approximation as format version 17 did (its median residuals in the detail
coefficients' class 0, ``code_image(..., estimate=True)``), not as files code it since version 18
(:mod:`bandelets.coding.approximation`): the margins above were measured with that model, and the new
one prices the smooth coarse band of the crease maps as cheaply as a faceted one, so that they
took 2 levels at 1 bpp (the estimate's raw ratio 0.71 against 0.94, the fandisk from the top at
0.68 to 0.74), where the finer levels' lifting, which the estimate misses, makes all the levels
win: the 512 x 512 crease map at 1 bpp decoded 63.61 dB instead of 73.10, -1.26 dB BD-PSNR over
format 17, the 256 one -0.34 (``benchmarks/rd_defaults.py``, with :data:`TRY_WITHIN` at 1.16).
With version 17's prices the level choices are the same as then and every map of issue 15 gains
or holds.

A quality target (PSNR, angle) is priced at the first threshold of its search, which may lie far
from its last (the bevel map at 256 and 35 dB: 0.036, where the file took 0.149), so it keeps all
the levels more often than a rate target does.
"""

from __future__ import annotations

import numpy as np

from ..coding.image import code_image, new_coders
from ..format.header import Header
from ..format.quantizer import dequantize, quantize
from ..transform.wavelets import coarse_blocks
from .lagrangian import LAMBDA

__all__ = [
    "CANDIDATES",
    "FRAMES_LEVELS",
    "FRAMES_PAY_BELOW",
    "MIN_LEVELS",
    "PAYS_BELOW",
    "TRY_WITHIN",
    "choose_levels",
    "levels_to_try",
]

#: Fewest levels the encoder chooses: one level lost 1.9 dB BD-PSNR against the default on the
#: fandisk rendered from the top, where two gained 1.8.
MIN_LEVELS = 2
#: Fewer levels are kept where their cost falls below this share of all the levels' cost: the
#: estimate leaves out the finer levels, which the directional lifting codes for less with more
#: levels above them (the crease map at 2 bpp: 0.87 estimated, yet 2.6 dB lost with 2 levels),
#: and the fandisk and bevel maps, which gained, came out at 0.70 to 0.83.
PAYS_BELOW = 0.85
#: The counts tried besides all the levels (the files that gained took 2 or 3; each count tried
#: costs about 8 ms at 512 x 512).
CANDIDATES = (MIN_LEVELS, MIN_LEVELS + 1)
#: The count tried besides all the levels on a normal map of three channels (in local frames):
#: two levels lost 2.2 dB at 0.25 bpp on fandisk's normal map at 256, where three gained 0.17.
FRAMES_LEVELS = MIN_LEVELS + 1
#: The share of all the levels' cost below which a normal map of three channels keeps
#: :data:`FRAMES_LEVELS`: between fandisk's normal map (0.945 to 0.956, gained) and bunny's
#: (0.987 to 0.994, lost).
FRAMES_PAY_BELOW = 0.97

#: Where the runner-up's estimated cost is within this factor of the count chosen, a rate target
#: also encodes it (:func:`levels_to_try`). The estimate prices the coarse band alone and misses
#: the finer levels' lifting and the restoration: on fandisk from the top at 0.35 bpp it chose 2
#: levels at 0.801 of all the levels' cost over 3 at 0.849, and 3 decoded 1.26 dB better (47.28
#: against 46.02 dB); at 0.5 bpp (0.814 against 0.869) 2 won by 0.88 dB. The standing 512 x 512
#: crease map at 1 bpp, 2 levels at 1.11 times all the levels' margin, is not tried. Not on
#: three channels: their margin (:data:`FRAMES_PAY_BELOW`) is within this factor of both counts'
#: costs at every rate, and the 14 files of fandisk's and bunny's normal maps (0.25 to 2 bpp) that
#: tried the other count gained 0.02 dB once, at twice the encoding time.
TRY_WITHIN = 1.08


def choose_levels(coefficients: list[np.ndarray], levels: int, threshold: float, frames: bool = False) -> int:
    """The count of CDF 9/7 levels, of :data:`CANDIDATES` and ``levels``, whose coarse part codes
    for the least ``error + LAMBDA T**2 bits`` at ``threshold``, where that saves enough: the
    first of :func:`levels_to_try`.

    Examples
    --------
    >>> from bandelets.samples import bevel_normal_map
    >>> from bandelets.format.samples import from_samples
    >>> from bandelets.transform.normals import equidistant
    >>> from bandelets.transform.bandelets import wavelet_coefficients
    >>> bevel = equidistant(from_samples(bevel_normal_map(128), "normal-map", 8))
    >>> choose_levels(wavelet_coefficients(bevel, "cdf97", 5), 5, 0.3)
    2
    """
    return levels_to_try(coefficients, levels, threshold, frames)[0]


def levels_to_try(
    coefficients: list[np.ndarray], levels: int, threshold: float, frames: bool = False
) -> tuple[int, ...]:
    """The count of CDF 9/7 levels :func:`choose_levels` chooses, and the runner-up where its cost
    is within :data:`TRY_WITHIN` of it (all the levels priced at :data:`PAYS_BELOW` times
    theirs; two channels only): a rate target encodes both and keeps the better file.

    Parameters
    ----------
    coefficients : list of ndarray, shape (H, W)
        The coefficients of every channel with ``levels`` levels
        (:func:`bandelets.transform.bandelets.wavelet_coefficients`, cdf97, symmetric extension).
    levels : int
    threshold : float
        The quantization threshold ``T`` expected.
    frames : bool
        The coefficients are those of a normal map of three channels, coded in local frames:
        only :data:`FRAMES_LEVELS` is tried, under :data:`FRAMES_PAY_BELOW`.

    Returns
    -------
    tuple of int
        The count chosen, then the runner-up if close.
    """
    if levels <= MIN_LEVELS:
        return (levels,)
    candidates, pays_below = ((FRAMES_LEVELS,), FRAMES_PAY_BELOW) if frames else (CANDIDATES, PAYS_BELOW)
    costs = dict.fromkeys(candidates + (levels,), 0.0)
    for c in coefficients:
        for candidate, block in coarse_blocks(c, levels, MIN_LEVELS).items():
            if candidate not in costs:
                continue
            q = quantize(block, threshold)
            header = Header(
                height=block.shape[0],
                width=block.shape[1],
                channels=1,
                kind="normal-map",
                transform="wavelet",
                wavelet="cdf97",
                levels=candidate - MIN_LEVELS,
                threshold=threshold,
            )
            _, _, spent = code_image(new_coders(), header, None, [q.ravel()], estimate=True)
            error = float(np.sum((block - dequantize(q, threshold)) ** 2))
            costs[candidate] += error + LAMBDA * threshold**2 * float(spent[0].sum())
    # All the levels compete at their cost times the margin: a count of fewer is chosen where it
    # costs less than that, the cheapest of them.
    costs[levels] *= pays_below
    ranked = sorted(costs, key=lambda c: (costs[c], -c))
    close = not frames and len(ranked) > 1 and costs[ranked[1]] < TRY_WITHIN * costs[ranked[0]]
    return (ranked[0], ranked[1]) if close else (ranked[0],)
