"""Direction-adaptive CDF 9/7 lifting at the finest wavelet levels (not in the paper).

Adaptive directional lifting (Ding, Wu and Li 2007; the direction-adaptive DWT of Chang and
Girod 2007): each of the four lifting steps of a CDF 9/7 pass predicts (or updates) a sample
from its two neighbours on the other polyphase channel read along a line of slope ``o``
(rows per column step, :data:`OFFSETS`) instead of straight across, with linear
interpolation between the samples of that channel. Any read of the other channel leaves a
lifting step exactly invertible, so the transform stays perfect-reconstruction whatever the
directions. A crease at an angle then leaves near-zero high-pass coefficients where the plain
separable filters leave a line of them at every level.

The slope is chosen per block of each pass (rows pass, then columns pass, of each of the
finest :data:`LEVELS` levels), shared by all channels (a crease is at the same place in every
component of a normal map), as the one whose prediction residuals would cost the fewest bits
at the threshold ``T`` (:func:`choose`), a slope other than zero paying :data:`PENALTY` bits
for its code. The encoder chooses them once per file, for the threshold its rate control
starts from; the decoder reads them from the file (:func:`code_fields`). The coarser levels
are plain CDF 9/7, as :func:`bandelets.transform.wavelets.wavedec` computes them, and every subband is
normalised by the same synthesis norms, so the layout, the quantizer and the context coder are unchanged.

Beside the slopes, two codes lift each pair of samples on its own (:data:`PAIR_BEFORE`,
:data:`PAIR_AFTER`): every lifting step reads one neighbour only, the one of the pair, with twice
the CDF 9/7 factor. That is a Haar transform (a step edge between two pairs of a flat region
leaves no high-pass sample at all, where CDF 9/7 leaves three or four that ring when quantized)
whose intermediate samples on a flat region are those of CDF 9/7, so blocks of either filter meet
without a seam and the coarser levels see the same low-pass. The two codes pair the samples either
way, so that a step at any place between two samples falls between two pairs of one of them. They
are chosen as the slopes are (:func:`choose`) and kept where they pay (:func:`lift`): on the
piecewise-flat or 8-bit-stepped maps, with a third lifted level where it pays (+3.7 dB BD-PSNR
on the lava flow, +0.8 and +2.3 dB on the crease maps at 256 and 512, +10.9 dB on a map of
bevelled plates, within 0.02 dB elsewhere).

The encoder keeps the directions only where they pay (:func:`pays`): on smooth maps (the
generated bumps at 1 to 2 bpp) they cost up to 0.7 dB at the same rate, and the file is then
coded with the plain wavelet (no directions, ``lifting`` 0 in its header).

Written here because no maintained library offers a direction-adaptive wavelet transform. The
passes are compiled, in place, as those of the plain CDF 9/7
(:func:`bandelets.transform.lifting.directional_pass`: a run of blocks of one slope along a line is lifted
in one loop, so where every slope is 0 a pass costs what the plain one does).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..coding import entropy
from ..format.header import MAX_LIFTING, FormatError
from ..format.quantizer import dequantize, quantize
from ..search.lagrangian import LAMBDA
from .lifting import ALPHA, BETA, DELTA, GAMMA, cdf97_pass, direction_costs, directional_pass
from .wavelets import _normalise, wavedec, waverec

__all__ = ["LEVELS", "OFFSETS", "N_CONTEXTS", "analysis", "synthesis", "choose", "code_fields"]

#: Slope of the prediction line (rows per column step) of each CDF 9/7 direction code; 0 is the
#: plain separable CDF 9/7. Steeper lines are the other pass's business.
SLOPES_97 = (0.0, 0.25, -0.25, 0.5, -0.5, 0.75, -0.75, 1.0, -1.0, 1.5, -1.5, 2.0, -2.0)
#: Lifting steps of the CDF 9/7 filters: the weights of the neighbour before and after.
_CDF97 = ((ALPHA, ALPHA), (BETA, BETA), (GAMMA, GAMMA), (DELTA, DELTA))
#: One-sided steps: each reads one neighbour with twice the CDF 9/7 factor, the low-pass sample
#: before the high-pass one (``PAIR_BEFORE``: pairs ``2k, 2k + 1``) or after it (``PAIR_AFTER``:
#: pairs ``2k + 1, 2k + 2``), so that each pair is lifted on its own (a Haar-like transform: a step
#: edge between two pairs leaves no high-pass sample) and a flat region gives every intermediate
#: sample that CDF 9/7 gives, so a block of either meets one of the other without a seam.
PAIR_BEFORE = ((2 * ALPHA, 0.0), (0.0, 2 * BETA), (2 * GAMMA, 0.0), (0.0, 2 * DELTA))
PAIR_AFTER = ((0.0, 2 * ALPHA), (2 * BETA, 0.0), (0.0, 2 * GAMMA), (2 * DELTA, 0.0))
#: Scaling of the pair codes after the CDF 9/7 one: the low-pass samples as CDF 9/7's, a high-pass
#: sample's synthesis of the norm of a CDF 9/7 one (1.0915), so the quantizer weighs both alike.
PAIR_HIGH_SCALE = 1.07008472317402 / 1.0915052823311142
_PAIR_SCALES = (1.0, PAIR_HIGH_SCALE)
#: Every direction code: ``(slope, steps, scales)``; code 0 is the plain CDF 9/7.
_CODES = [(o, _CDF97, (1.0, 1.0)) for o in SLOPES_97] + [
    (0.0, PAIR_BEFORE, _PAIR_SCALES),
    (0.0, PAIR_AFTER, _PAIR_SCALES),
]
#: Slope of the lifting line of each code (rows per column step).
OFFSETS = np.array([code[0] for code in _CODES])
#: Weights of the neighbour before and after of each lifting step of each code.
WEIGHTS = np.array([code[1] for code in _CODES])
#: Factors of the low- and high-pass samples of each code after the CDF 9/7 scaling.
SCALES = np.array([code[2] for code in _CODES])
#: Finest levels lifted along directions, by default.
LEVELS = 2
#: Side of a block of one direction, in samples of the pass's input (rows; half as many
#: columns of each output band).
BLOCK = 8
#: Price of a direction other than the plain one, in bits (see :func:`choose`): 6 gained +0.03 to
#: +0.07 dB BD-PSNR over 4 on the crease map, the acacia door and the fandisk normals at 256
#: (2.5 lost as much; 9 lost 0.16 dB on the fandisk normals).
PENALTY = 6.0
#: Further price of a Haar code, in bits.
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

_N_STATE = 3
#: The "moved" flag of a block counts its left and upper neighbours moved too (0 to 2).
_N_NEAR = 3
#: Contexts of the direction coder: "moved" flags by pass, level and neighbours, then the symbols'
#: one model.
N_CONTEXTS = 2 * MAX_LIFTING * _N_STATE * _N_NEAR + 16


def _block_shape(shape: tuple[int, int]) -> tuple[int, int]:
    return -(-shape[0] // BLOCK), -(-shape[1] // 2 // (BLOCK // 2))


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

    if len(blocks) > 1 and blocks[0].size >= THREADS_FROM:  # the channels in threads (nogil kernels)
        with ThreadPoolExecutor(max_workers=len(blocks)) as pool:
            return sum(pool.map(bits, blocks))
    return sum(map(bits, blocks))


def _passes(shape: tuple[int, int], lifting: int):
    """``(level, pass, (rows, cols) of the pass's input)`` of the directional passes, in order."""
    h, w = shape
    out = []
    for level in range(1, lifting + 1):
        out += [(level, 0, (h, w)), (level, 1, (w, h))]
        h, w = h // 2, w // 2
    return out


def field_shapes(shape: tuple[int, int], lifting: int) -> list[tuple[int, int]]:
    """Shape of the block codes of every directional pass of a ``shape`` channel."""
    return [_block_shape(size) for *_, size in _passes(shape, lifting)]


def analysis(
    channels,
    levels: int,
    lifting: int = LEVELS,
    fields: list[np.ndarray] | None = None,
    threshold: float = 0.0,
    pairs: bool = True,
    first: np.ndarray | None = None,
):
    """Normalised direction-adaptive wavelet coefficients of channels sharing one geometry.

    Parameters
    ----------
    channels : sequence of ndarray, shape (H, W) each
        ``H`` and ``W`` multiples of ``2**levels``.
    levels : int
        Wavelet levels.
    lifting : int
        Finest levels lifted along directions, at most ``levels``.
    fields : list of ndarray of int, optional
        Direction codes of every pass (:func:`field_shapes`); chosen (:func:`choose`) if None.
    threshold : float
        With ``fields`` None: the ``T`` the directions are chosen for (> 0).
    pairs : bool
        With ``fields`` None: whether the pair codes may be chosen (else the slopes alone).
    first : ndarray, optional
        With ``fields`` None: :func:`first_costs` of the channels, if the caller has them.

    Returns
    -------
    coefficients : list of ndarray, shape (H, W), Mallat layout as :func:`bandelets.transform.wavelets.wavedec`
    fields : list of ndarray of int
    """
    outs = [np.array(x, dtype=np.float64, order="C") for x in channels]
    works = [np.empty_like(o) for o in outs]
    shape = outs[0].shape
    chosen = []
    for i, (level, p, _) in enumerate(_passes(shape, lifting)):
        h, w = shape[0] >> (level - 1), shape[1] >> (level - 1)
        # The rows pass from the channel into the work array, the columns pass back.
        sources = [o[:h, :w] if p == 0 else k[:h, :w].T for o, k in zip(outs, works, strict=True)]
        if fields is not None:
            codes = np.asarray(fields[i], np.int64)
        else:  # the first pass reads the channels themselves: its costs are the caller's, if given
            codes = choose(sources, threshold, pairs, first if i == 0 else None)
        chosen.append(codes)
        for o, k, source in zip(outs, works, sources, strict=True):
            directional_pass(
                source, k[:h, :w] if p == 0 else o[:h, :w].T, True, codes, OFFSETS, WEIGHTS, SCALES, BLOCK
            )
    for o, k in zip(outs, works, strict=True):
        _plain(o, k, levels, lifting, True)
    return outs, chosen


def transform(
    x: np.ndarray, levels: int, lifting: int, fields: list[np.ndarray], inverse: bool = False
) -> np.ndarray:
    """:func:`analysis` of one channel ``x`` (``inverse``: :func:`synthesis` of coefficients
    ``x``) for given directions, in place on ``x`` (float64, row-major), which it returns."""
    work = np.empty_like(x)
    shape = x.shape
    passes = list(enumerate(_passes(shape, lifting)))
    if inverse:
        _plain(x, work, levels, lifting, False)
        passes.reverse()
    for i, (level, p, _) in passes:
        h, w = shape[0] >> (level - 1), shape[1] >> (level - 1)
        ends = (x[:h, :w], work[:h, :w]) if p == 0 else (work[:h, :w].T, x[:h, :w].T)
        source, target = ends[::-1] if inverse else ends
        codes = np.asarray(fields[i], np.int64)
        directional_pass(source, target, not inverse, codes, OFFSETS, WEIGHTS, SCALES, BLOCK)
    if not inverse:
        _plain(x, work, levels, lifting, True)
    return x


def _plain(x: np.ndarray, work: np.ndarray, levels: int, lifting: int, forward: bool) -> None:
    """The plain CDF 9/7 levels above the ``lifting`` finest ones of ``x`` and the normalisation
    (forward: after the levels; inverse: before them), in place."""
    if forward:
        for level in range(lifting + 1, levels + 1):
            block = x[: x.shape[0] >> (level - 1), : x.shape[1] >> (level - 1)]
            scratch = work[: block.shape[0], : block.shape[1]]
            cdf97_pass(block, scratch, True)
            cdf97_pass(scratch.T, block.T, True)
        _normalise(x, "cdf97", levels)
        return
    _normalise(x, "cdf97", levels, inverse=True)
    for level in range(levels, lifting, -1):
        block = x[: x.shape[0] >> (level - 1), : x.shape[1] >> (level - 1)]
        scratch = work[: block.shape[0], : block.shape[1]]
        cdf97_pass(block.T, scratch.T, False)
        cdf97_pass(scratch, block, False)


def synthesis(coefficients: np.ndarray, levels: int, lifting: int, fields: list[np.ndarray]) -> np.ndarray:
    """Inverse of :func:`analysis` for one channel: ``(H, W)`` coefficients to samples."""
    return transform(
        np.array(coefficients, dtype=np.float64, order="C"), levels, lifting, fields, inverse=True
    )


def code_fields(coder: entropy.Coder, fields: list[np.ndarray] | None, shape, lifting: int, base: int):
    """Code (``fields`` given) or decode the direction codes of every pass.

    Coarse level first, rows pass then columns pass. Each block's "moved" flag (a direction other
    than the plain one) has the context of its pass, of the block coded before at its place: in
    the rows pass of the same level for a columns pass, in the rows pass of the next coarser level
    for a rows pass (none for the coarsest), and of how many of its left and upper neighbours
    moved (since format version 11: a crease moves a line of blocks; 10 to 16 % fewer bits for the
    directions of the 256 x 256 crease and fandisk normal maps at 0.5 and 1 bpp). The other codes
    are symbols of one adaptive model for every pass (format version 17: the passes choose alike,
    and a model per pass spent 6 to 8 % more on the symbols of the fandisk rendered from the top
    at 256, learning its 14 codes six times over a few dozen blocks each). Contexts from
    ``base`` on (:data:`N_CONTEXTS` of them).
    """
    shapes = field_shapes(shape, lifting)
    out: list = [None] * len(shapes)
    for level in range(lifting - 1, -1, -1):
        for p in (0, 1):
            i = 2 * level + p
            size = shapes[i]
            if p == 1:
                state = (out[i - 1] == 0).T.astype(np.int64)
            elif level + 1 < lifting:
                coarse = out[i + 2] == 0
                r = np.minimum(np.arange(size[0]) // 2, coarse.shape[0] - 1)
                c = np.minimum(np.arange(size[1]) // 2, coarse.shape[1] - 1)
                state = coarse[r[:, None], c[None, :]].astype(np.int64)
            else:
                state = np.full(size, 2, np.int64)
            codes = np.zeros(size, np.int64) if fields is None else np.asarray(fields[i], np.int64)
            contexts = base + (i * _N_STATE + state) * _N_NEAR
            moved = np.nonzero(entropy.code_flag_map(coder, codes != 0, contexts, 1).ravel())[0]
            symbols = entropy.code_symbols(
                coder,
                codes.ravel()[moved] - 1,
                np.full(moved.shape, base + 2 * MAX_LIFTING * _N_STATE * _N_NEAR),
                np.full(moved.shape, 4),
            )
            if np.any(symbols >= len(OFFSETS) - 1):
                raise FormatError("corrupt .bdl file: lifting direction out of range")
            decoded = np.zeros(size[0] * size[1], np.int64)
            decoded[moved] = symbols + 1
            out[i] = decoded.reshape(size)
    return out


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
    below = PAYS_BELOW_FRAMES if frames else PAYS_BELOW
    return cost_ratio(channels, lifted, fields, levels, lifting, threshold, plain, lifted_cost) < below


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
    coder = entropy.Coder(N_CONTEXTS)
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
    deep, deep_fields = analysis(channels, levels, deeper, threshold=threshold, first=first)
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
    slopes = analysis(channels, levels, lifting, threshold=threshold, pairs=False, first=first)
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
