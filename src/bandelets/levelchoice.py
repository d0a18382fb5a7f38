"""How many wavelet levels a normal map is coded with: the encoder's choice, at the threshold it
expects (format unchanged: the header holds the levels).

The coarse approximation is coded as the residual of the median predictor of LOCO-I
(:func:`bandelets.entropy.code_coefficients`), an intra prediction in all but name. On
piecewise-flat maps (facets, flat backgrounds, bevels with a flat top) that prediction codes a
coarse approximation for less than the CDF 9/7 levels that would split it further, whose long
synthesis functions also spread each edge's quantization error far around it: stopping at 2
levels gained +1.76 dB BD-PSNR on the fandisk rendered from the top and +0.62 on the bevel map at
256, while the smooth bumps map lost 2.7 dB (BENCHMARKS, "Fewer levels where the median predictor
codes the coarse band for less"). So the encoder tries every count of levels from
:data:`MIN_LEVELS` up, on the part of the image they differ on: the approximation of
:data:`MIN_LEVELS` levels, coded as it is, or split by each further level as the codec would code
it; each priced by the coefficient coder itself (its ideal code length) and the quantization
error, ``error + LAMBDA T**2 bits``, and the cheapest kept where it saves enough
(:data:`PAYS_BELOW`). That part is a sixteenth of the
image or less: its coding costs a few percent of an encoding.
"""

from __future__ import annotations

import numpy as np

from .bitstream import Header
from .coding import code_image, new_coders
from .lagrangian import LAMBDA
from .quantize import dequantize, quantize
from .transform import wavelet_coefficients

__all__ = ["MIN_LEVELS", "PAYS_BELOW", "choose_levels"]

#: Fewest levels the encoder chooses: one level lost 1.9 dB BD-PSNR against the default on the
#: fandisk rendered from the top, where two gained 1.8.
MIN_LEVELS = 2
#: Fewer levels are kept where their cost falls below this share of all the levels' cost: the
#: estimate leaves out the finer levels, which the directional lifting codes for less with more
#: levels above them (the crease map at 2 bpp: 0.87 estimated, yet 2.6 dB lost with 2 levels),
#: and the fandisk and bevel maps, which gained, came out at 0.70 to 0.83.
PAYS_BELOW = 0.85


def choose_levels(coded: np.ndarray, wavelet: str, levels: int, threshold: float) -> int:
    """The count of wavelet levels, from :data:`MIN_LEVELS` to ``levels``, whose coarse part codes
    for the least ``error + LAMBDA T**2 bits`` at ``threshold``.

    Parameters
    ----------
    coded : ndarray, shape (H, W, C)
        The channels the codec transforms (symmetric extension).
    wavelet : str
        Their wavelet (a name of :data:`bandelets.bitstream.WAVELETS`).
    levels : int
        The most levels (:func:`bandelets.wavelets.max_levels`).
    threshold : float
        The quantization threshold ``T`` expected.

    Returns
    -------
    int
    """
    if levels <= MIN_LEVELS:
        return levels
    costs = {}
    for candidate in range(MIN_LEVELS, levels + 1):
        total = 0.0
        for c in wavelet_coefficients(coded, wavelet, candidate):
            # The approximation of MIN_LEVELS levels, split candidate - MIN_LEVELS times more.
            h, w = c.shape[0] >> MIN_LEVELS, c.shape[1] >> MIN_LEVELS
            block = c[:h, :w]
            q = quantize(block, threshold)
            header = Header(
                height=h,
                width=w,
                channels=1,
                kind="normal-map",
                transform="wavelet",
                wavelet=wavelet,
                levels=candidate - MIN_LEVELS,
                threshold=threshold,
            )
            _, _, spent = code_image(new_coders(), header, None, [q.ravel()])
            error = float(np.sum((block - dequantize(q, threshold)) ** 2))
            total += error + LAMBDA * threshold**2 * float(spent[0].sum())
        costs[candidate] = total
    fewer = [candidate for candidate in costs if costs[candidate] < PAYS_BELOW * costs[levels]]
    return min(fewer, key=costs.get) if fewer else levels
