"""The encoder's choice of the directions of the lifting (:mod:`bandelets.transform.directional`):
per block, the direction of least estimated bits; per file, whether the directions pay, with the
pair codes or the slopes alone, and at how many levels.
"""

from __future__ import annotations

import numpy as np

from ..coding.directions import N_CONTEXTS, code_fields
from ..coding.rangecoder import Coder
from ..format.fields import MAX_LIFTING
from ..format.quantizer import dequantize, quantize
from ..runtime.threads import each
from ..transform.directional import (
    BLOCK,
    OFFSETS,
    SCALES,
    SLOPES_97,
    WEIGHTS,
    analysis,
    field_shapes,
    synthesis,
)
from ..transform.lifting import direction_costs
from ..transform.wavelets import wavedec, waverec
from .lagrangian import LAMBDA

__all__ = [
    "PAYS_BELOW",
    "PAYS_BELOW_FRAMES",
    "choose",
    "chosen_analysis",
    "cost",
    "cost_ratio",
    "lift",
    "pays",
    "ratio_pays",
]


def chosen_analysis(
    channels,
    levels: int,
    lifting: int,
    threshold: float,
    pairs: bool = True,
    first: np.ndarray | None = None,
):
    """:func:`bandelets.transform.directional.analysis` with the directions of every pass chosen for
    the threshold ``T`` (:func:`choose`; ``pairs``: the pair codes may be chosen, else the slopes
    alone); ``first``: :func:`first_costs` of the channels when the caller has them (the first pass
    reads the channels themselves)."""
    return analysis(
        channels,
        levels,
        lifting,
        choose=lambda i, sources: choose(sources, threshold, pairs, first if i == 0 else None),
    )


#: Price of a direction other than the plain one, in bits (see :func:`choose`): 6 gained +0.03 to
#: +0.07 dB BD-PSNR over 4 on the crease map, the acacia door and the fandisk normals at 256
#: (2.5 lost as much; 9 lost 0.16 dB on the fandisk normals).
PENALTY = 6.0


#: The pair codes are kept where they bring the estimated cost of a file below this fraction of
#: that of the slopes alone (:func:`lift`): 0.95 lost 0.14 dB BD-PSNR to 0.9 on the 256 x 256
#: crease map (at 0.5 and 0.7 bpp), and with the pair codes kept everywhere the acacia door lost
#: 0.16 dB, the fandisk normals 0.11 dB, the crease map 0.3 dB at 0.25 to 0.5 bpp.
PAIRS_PAY_BELOW = 0.9


#: Levels lifted beyond :data:`LEVELS` where the pair codes pay and the estimate says so
#: (:func:`lift`): +0.33 dB BD-PSNR on the 256 x 256 crease map, +5.1 dB on a map of bevelled
#: plates, the same files elsewhere; 3 levels for every file lost 0.13 dB on the lava flow and
#: 0.07 dB on the acacia door.
DEEPER = 1


#: Samples of a pass from which :func:`choose` searches the channels in parallel threads.
THREADS_FROM = 256 * 256


#: The directions are kept where they bring the estimated cost of a file below this fraction of
#: the plain wavelet's (:func:`pays`).
PAYS_BELOW = 0.885


#: The same for the three channels of a normal map coded in local frames, whose estimate (made
#: on the channels x, y, z as they are) flatters the directions less: with their quantization
#: optimised too, 0.96 gained +0.43 dB BD-PSNR over 0.905 on the bunny's normal map and +0.08 on
#: the fandisk's (-0.16 dB at 0.25 bpp, +1 dB at 2 bpp), at 0.25 to 2 bpp.
PAYS_BELOW_FRAMES = 0.96


def choose(
    blocks: list[np.ndarray], threshold: float, pairs: bool = True, costs: np.ndarray | None = None
) -> np.ndarray:
    """Direction code of every block of one pass over ``blocks`` (the channels, same shape).

    The one of least ``sum log2(1 + 2 |d| / T)`` over the block's high-pass samples ``d`` (before
    the final scaling) with that direction everywhere: about the bits of the coefficients that survive the
    threshold ``T``, nothing for those far below it; any direction but the plain one pays
    :data:`PENALTY` more. Measured on 256 x 256 maps without restoration (BD-PSNR of the lifted
    coder over the plain one, scripts not kept): the sum of ``|d|`` with a penalty of ``5 T``
    gained 0.04 dB less on the crease map and 0.1 dB less on the acacia door; the residual of
    the first prediction step alone (a quarter of the time) as much on the crease map but
    0.7 dB less on the smooth bumps, where it lost 0.8 dB to the plain coder.

    The pair codes (``pairs``; else the slopes alone) are priced as the slopes, their high-pass
    samples counted at the scale they are coded at (:data:`SCALES`). ``costs``: those of every code
    (before the prices) when the caller has them, as :func:`first_costs` makes them.
    """

    n = len(OFFSETS) if pairs else len(SLOPES_97)
    costs = first_costs(blocks, threshold, n) if costs is None else costs[:n].copy()
    costs[1:] += PENALTY
    return np.argmin(costs, axis=0)


def first_costs(blocks: list[np.ndarray], threshold: float, n: int | None = None) -> np.ndarray:
    """``costs[i, a, b]``: :func:`bandelets.transform.lifting.direction_costs` of the first ``n`` codes (all
    if None), summed over ``blocks`` (the channels, in threads where they are large)."""
    n = len(OFFSETS) if n is None else n

    def bits(x: np.ndarray) -> np.ndarray:
        return direction_costs(x, OFFSETS[:n], WEIGHTS[:n], SCALES[:n], BLOCK, threshold)

    return sum(each(bits, blocks, threaded=blocks[0].size >= THREADS_FROM))  # nogil kernels


def pays(
    channels,
    lifted: list[np.ndarray],
    fields: list[np.ndarray],
    levels: int,
    lifting: int,
    threshold: float,
    frames: bool = False,
    plain: list[np.ndarray] | None = None,
    lifted_cost: float | None = None,
) -> bool:
    """Whether the directions ``fields`` pay on ``channels`` at the threshold ``T``: whether
    :func:`cost_ratio` is below :data:`PAYS_BELOW` (``frames``, the channels of a normal map
    coded in local frames: :data:`PAYS_BELOW_FRAMES`).

    Below 1, because the estimate flatters the directions at low rates: with the restoration and
    the context coder, the files lifted at a ratio of 0.89 to 0.91 lost 0.1 to 0.4 dB at the same
    size (the 256 x 256 crease map at 0.25 and 0.35 bpp, the acacia door at 0.25 bpp), those at
    0.88 and below gained 0.2 to 7 dB (the crease map from 0.5 bpp, at 512 from 0.25 bpp, the
    acacia door from 1 bpp), save the acacia door at 0.5 bpp (0.875, -0.14 dB). On the smooth
    bumps and the lava flow the ratio is 1.00 to 1.01 at every rate: directions there lost up to
    0.7 dB.

    ``plain``: the CDF 9/7 coefficients of ``channels`` when the caller has them (else made again);
    ``lifted_cost``: the :func:`cost` of ``lifted`` when the caller has it (:func:`lift`).
    """
    ratio = cost_ratio(channels, lifted, fields, levels, lifting, threshold, plain, lifted_cost)
    return ratio_pays(ratio, frames)


def ratio_pays(ratio: float, frames: bool = False) -> bool:
    """Whether directions of :func:`cost_ratio` ``ratio`` pay (:func:`pays`, for a caller that has the
    ratio)."""
    return ratio < (PAYS_BELOW_FRAMES if frames else PAYS_BELOW)


def cost_ratio(
    channels,
    lifted: list[np.ndarray],
    fields: list[np.ndarray],
    levels: int,
    lifting: int,
    threshold: float,
    plain: list[np.ndarray] | None = None,
    lifted_cost: float | None = None,
) -> float:
    """:func:`cost` of the lifted coefficients ``lifted`` (directions ``fields``; ``lifted_cost`` if
    given) over that of the plain CDF 9/7 ones of ``channels`` (``plain``, if given)."""
    if plain is None:
        plain = [wavedec(np.array(x, dtype=np.float64), "cdf97", levels) for x in channels]
    reference = cost(channels, plain, None, levels, lifting, threshold)
    if lifted_cost is None:
        lifted_cost = cost(channels, lifted, fields, levels, lifting, threshold)
    return lifted_cost / reference if reference > 0 else 1.0


def cost(
    channels,
    coefficients: list[np.ndarray],
    fields: list[np.ndarray] | None,
    levels: int,
    lifting: int,
    threshold: float,
) -> float:
    """``D + LAMBDA T**2 R`` of ``coefficients`` lifted with directions ``fields`` (None: the plain
    CDF 9/7), ``D`` the squared error of the channels after quantization at the threshold ``T`` (no
    restoration), ``R`` the bits of the coefficients estimated as :func:`choose` does, plus the
    coded directions."""
    if fields is None:
        side = [np.zeros(shape, np.int64) for shape in field_shapes(channels[0].shape, lifting)]
        synthesise = lambda c: waverec(c, "cdf97", levels)  # noqa: E731
    else:
        side = fields
        synthesise = lambda c: synthesis(c, levels, lifting, fields)  # noqa: E731
    coder = Coder(N_CONTEXTS)
    code_fields(coder, side, channels[0].shape, lifting, 0)

    bits = 8.0 * len(coder.finish())
    error = 0.0
    for x, c in zip(channels, coefficients, strict=True):
        bits += float(np.sum(np.log2(1.0 + np.abs(c) * (2.0 / threshold))))
        error += float(np.sum((synthesise(dequantize(quantize(c, threshold), threshold)) - x) ** 2))
    return error + LAMBDA * threshold**2 * bits


def lift(channels, levels: int, lifting: int, threshold: float):
    """:func:`analysis` of ``channels`` with the directions chosen for ``T`` (``threshold``), with
    the pair codes where they pay: where they bring the :func:`cost` below :data:`PAIRS_PAY_BELOW`
    of that of the slopes alone, else with the slopes alone. With the pair codes, also at one level
    more than ``lifting`` (at most ``levels`` and ``MAX_LIFTING``) where that costs less.

    Returns
    -------
    coefficients, fields : as :func:`analysis`
    lifted : int
        The levels lifted, ``lifting`` or one more.
    cost : float or None
        The :func:`cost` of the coefficients, where it was needed (None: no block took a pair code).
    """
    deeper = min(lifting + DEEPER, levels, MAX_LIFTING)
    # Not copied (each analysis copies its input), and at most two sets of coefficients held at
    # once besides the analysis running: the peak of a 2048 x 2048 encode (1 GiB target).
    channels = [np.ascontiguousarray(x, dtype=np.float64) for x in channels]
    first = first_costs(channels, threshold)  # the first pass reads the channels in both analyses
    deep, deep_fields = chosen_analysis(channels, levels, deeper, threshold, first=first)
    # The finer levels' directions are those of an analysis of ``lifting`` levels.
    fields = deep_fields[: 2 * lifting]
    if not any(np.any(f >= len(SLOPES_97)) for f in deep_fields):
        if deeper > lifting:
            del deep
            deep = analysis(channels, levels, lifting, fields)[0]
        return deep, fields, lifting, None
    # The candidates, in order (the first of equal costs kept): the slopes alone, the pair codes
    # at ``lifting`` levels, at ``deeper`` levels; a pair candidate only below PAIRS_PAY_BELOW.
    deep_cost = cost(channels, deep, deep_fields, levels, deeper, threshold) if deeper > lifting else None
    if deep_cost is None:  # ``deep`` is the pair codes at ``lifting`` levels: no third candidate
        lifted, deep = deep, None
    slopes = chosen_analysis(channels, levels, lifting, threshold, pairs=False, first=first)
    without = cost(channels, *slopes, levels, lifting, threshold)
    best = (*slopes, lifting, without)
    del slopes
    if deep is not None and not deep_cost < PAIRS_PAY_BELOW * without:
        deep = None  # it cannot be kept: the slopes' set is the only one held
    elif deep is not None:
        # ``deep`` beats the slopes alone: only the pair codes at ``lifting`` levels may beat it.
        best = (deep, deep_fields, deeper, deep_cost)
        del deep
    if any(np.any(f >= len(SLOPES_97)) for f in fields):
        if deep_cost is not None:
            lifted = analysis(channels, levels, lifting, fields)[0]
        estimate = cost(channels, lifted, fields, levels, lifting, threshold)
        # Kept over the slopes alone when below both, over the deeper when not above it.
        beaten = estimate < best[3] or (best[2] == deeper > lifting and estimate == best[3])
        if estimate < PAIRS_PAY_BELOW * without and estimate < without and beaten:
            best = (lifted, fields, lifting, estimate)
    return best
