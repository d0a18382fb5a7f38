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

from collections.abc import Callable

import numpy as np

from .lifting import ALPHA, BETA, DELTA, GAMMA, cdf97_pass, directional_pass
from .wavelets import _normalise

__all__ = [
    "BLOCK",
    "LEVELS",
    "OFFSETS",
    "SCALES",
    "SLOPES_97",
    "WEIGHTS",
    "analysis",
    "field_shapes",
    "synthesis",
    "transform",
]

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


def _block_shape(shape: tuple[int, int]) -> tuple[int, int]:
    return -(-shape[0] // BLOCK), -(-shape[1] // 2 // (BLOCK // 2))


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
    choose: Callable[[int, list[np.ndarray]], np.ndarray] | None = None,
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
        Direction codes of every pass (:func:`field_shapes`).
    choose : callable, optional
        With ``fields`` None: ``choose(i, sources)``, the codes of pass ``i`` given its inputs (one
        array per channel): the encoder's search, :func:`bandelets.search.directions.chosen_analysis`.

    Returns
    -------
    coefficients : list of ndarray, shape (H, W), Mallat layout as
    :func:`bandelets.transform.wavelets.wavedec`
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
        else:
            codes = choose(i, sources)
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
