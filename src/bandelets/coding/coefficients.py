"""The context model of the wavelet and bandelet coefficients (the coefficients stream), driving the
range coder of :mod:`bandelets.coding.rangecoder`.

The coefficient contexts (:func:`code_coefficients`) are many (class x neighbours x guide) and a
256 x 256 map at 0.25 bpp uses about 1,500 of them a few times each: learning each one from 1/2
cost about a sixth of such a file. So each of them is backed by the same context shared by all
the classes, which it outweighs as it is used
(:func:`code_backed`): +0.3 dB BD-PSNR on the crease map, +0.1 to +0.2 on the others
(BENCHMARKS, "Context modelling of format version 9"). The 1D coefficients of the bandelet
squares have significance and sign contexts of their own, refined by what
:mod:`bandelets.coding.squarecontexts` reads around their square (format version 10).

Those contexts see the neighbours' magnitudes clipped at 2. Since format version 16 the
significance and the first two magnitude decisions of a detail coefficient also read an
*activity* context (its class, the octave of its neighbours' and parent's full magnitudes, the
octave of the guide's), whose probability is mixed with the backed one in the logistic domain
by weights learned as the stream goes (:func:`code_mixed`, a two-input mixer after PAQ's), and
the Elias-gamma prefix of the larger magnitudes and the first bit below its leading one are
read in contexts of that activity: the coefficient streams of the maps of issue 15 are 1 to 2 %
shorter at the same threshold (BENCHMARKS, "Mixed contexts"), for about 10 ms more to decode
the 512 x 512 crease map at 1 bpp (entropy decoding 33 ms instead of 22).

The context table's layout: each group of contexts starts where the one before ends (``_SIG`` to
``_N_COEFF_CONTEXTS``), so that one table serves every decision of a coefficient; the approximation's
contexts follow it (:func:`coefficient_contexts`, :mod:`bandelets.coding.approximation`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .rangecoder import (
    COST_SCALE,
    EG_PREFIX,
    N_INPUTS,
    SPENT,
    Coder,
    CorruptStream,
    code_backed,
    code_mixed,
    elias_gamma,
    keep_registers,
    kernel,
    octave,
    registers,
)

__all__ = [
    "MAX_MAGNITUDE",
    "N_CLASSES",
    "N_HINTS",
    "SQUARE_START",
    "code_coefficients",
    "coefficient_contexts",
    "median_of",
    "median_prediction",
    "neighbourhood",
]


#: Coefficient context classes: 0 approximation, 1-15 wavelet (orientation x level 1 to 5+),
#: 16-30 bandelet (square width 4, 8, 16+ x 1D scale bucket).
N_CLASSES = 31


_N_SUM = 8


_SUM_BUCKET = np.array([0, 1, 2, 3, 4, 5, 5, 6, 6, 6, 7, 7, 7, 7, 7], np.int64)


# Context table layout of the coefficient stream. Class 0 is the approximation, which files code
# with :mod:`bandelets.coding.approximation` in contexts of its own after these (format version 18).
_APPROXIMATION = 0


#: Largest magnitude a decoded coefficient may have (the quantizer's MAX_INDEX).
MAX_MAGNITUDE = 2**30


_N_GUIDE = 4  # the guide channel's magnitude at the same place: 0, 1, 2+, or no guide
#: Sign contexts: the signs (none, +, -) of the left neighbour, of the guide and of the upper one.
_N_SIGN = 3 * 3 * 3


_SIG = 0


_GT1 = _SIG + N_CLASSES * _N_SUM * 3 * _N_GUIDE


_GT2 = _GT1 + N_CLASSES * 5 * _N_GUIDE


_PREFIX = _GT2 + N_CLASSES * 5 * _N_GUIDE


_SIGN = _PREFIX + N_CLASSES * EG_PREFIX


# The coarse contexts that back them (:func:`code_backed`): the same contexts without the class.
_SIG_COARSE = _SIGN + N_CLASSES * _N_SIGN


_GT1_COARSE = _SIG_COARSE + _N_SUM * 3 * _N_GUIDE


_GT2_COARSE = _GT1_COARSE + 5 * _N_GUIDE


_SIGN_COARSE = _GT2_COARSE + 5 * _N_GUIDE


_PREFIX_COARSE = _SIGN_COARSE + _N_SIGN


# The bandelet classes' own significance and sign contexts (:func:`_bandelet_significance`,
# :func:`_bandelet_sign`), backed by the same coarse ones.
_FIRST_BANDELET = 16


#: Number of hints a bandelet coefficient's significance context adds
#: (:func:`bandelets.coding.squarecontexts.square_hints`), and the flag of a square's first coefficient.
N_HINTS = 24


SQUARE_START = 1 << 8


_BSIG = _PREFIX_COARSE + EG_PREFIX


_BSIGN = _BSIG + (N_CLASSES - _FIRST_BANDELET) * _N_SUM * 3 * _N_GUIDE * N_HINTS


# Format version 16: the significance and the first two magnitude decisions mix their fine and
# coarse contexts with a third, the *activity* context (:func:`code_mixed`): the class, the octave
# of the neighbours' full magnitudes (``_N_ACTIVITY``: the contexts above clip them at 2) and the
# octave of the guide's magnitude (``_N_GUIDE_OCTAVES``). The Elias-gamma prefix of the larger
# magnitudes is read in a context of the class and that activity, backed by the class's, and so is
# the first bit below its leading one (``_FIRST_BELOW``: the larger half of an octave is the rarer).
_N_ACTIVITY = 12


_N_GUIDE_OCTAVES = 6


_ACTIVITY = _BSIGN + (N_CLASSES - _FIRST_BANDELET) * 2 * _N_SIGN


_PREFIX_ACTIVE = _ACTIVITY + 3 * N_CLASSES * _N_ACTIVITY * _N_GUIDE_OCTAVES


_FIRST_BELOW = _PREFIX_ACTIVE + N_CLASSES * _N_ACTIVITY * EG_PREFIX


_FIRST_BELOW_COARSE = _FIRST_BELOW + N_CLASSES * _N_ACTIVITY * EG_PREFIX


_MIX = _FIRST_BELOW_COARSE + N_CLASSES * EG_PREFIX


_N_COEFF_CONTEXTS = _MIX + 3 * N_CLASSES * 3 * N_INPUTS


_NO_HINTS = np.zeros(0, np.int64)


@njit(cache=True, nogil=True, inline="always")
def neighbourhood(known, positions):
    """Left, up, up-left and up-right of a bin (``positions``: -1 where absent), replicated
    where absent as the predictor wants them."""
    up = known[positions[1]] if positions[1] >= 0 else (known[positions[0]] if positions[0] >= 0 else 0)
    left = known[positions[0]] if positions[0] >= 0 else up
    corner = known[positions[2]] if positions[2] >= 0 else up
    right = known[positions[3]] if positions[3] >= 0 else up
    return left, up, corner, right


@njit(cache=True, nogil=True, inline="always")
def median_prediction(known, positions):
    """The median edge detector of LOCO-I on the bins ``known`` around ``positions``."""
    left, up, corner, _ = neighbourhood(known, positions)
    return median_of(left, up, corner)


@njit(cache=True, nogil=True, inline="always")
def median_of(left, up, corner):
    """The median edge detector of LOCO-I: left or up at an edge, the plane through the three
    elsewhere."""
    if corner >= max(left, up):
        return min(left, up)
    if corner <= min(left, up):
        return max(left, up)
    return left + up - corner


# One kernel for both sides, the ``decoding`` flag read at run time: a decoder and an encoder each
# compiled with their constant flag decoded 8 % faster, but took twice the first run's compilation.
@kernel
def _coefficients(
    st, buf, probs, counts, q, known, guide, spent, order, classes, neighbours, hints, decoding
):
    r = registers(st)
    status = 0
    agree = 0  # in a bandelet square: signs equal to the guide's so far, minus those opposite
    for i in range(order.shape[0]):
        at = order[i]
        before = r[SPENT]
        cls = classes[i]
        left, up = _full(known, neighbours[i, 0]), _full(known, neighbours[i, 1])
        corner, across = _full(known, neighbours[i, 2]), _full(known, neighbours[i, 3])
        coarser, sibling = _full(known, neighbours[i, 4]), _full(known, neighbours[i, 5])
        # The contexts of version 15 see the magnitudes clipped at 2, the activity all of them.
        total = 2 * min(left, 2) + 2 * min(up, 2) + min(corner, 2) + min(across, 2)
        near = _SUM_BUCKET[total + min(sibling, 2)]
        parent = min(coarser, 2)
        activity = 2 * left + 2 * up + corner + across + 2 * coarser + sibling
        # An approximation given here (the level choice's estimate, :mod:`bandelets.search.levelchoice`)
        # is coded as in version 17: its residual from the median predictor in the contexts of
        # class 0. Files code it with :mod:`bandelets.coding.approximation`.
        predicted = median_prediction(known, neighbours[i]) if cls == _APPROXIMATION else 0
        value = q[at] - predicted
        m = abs(value)
        g = min(abs(guide[at]), 2) if guide.shape[0] > 0 else 3
        ctx = (near * 3 + parent) * _N_GUIDE + g
        activity_octave = octave(activity, _N_ACTIVITY - 1)
        guided = octave(abs(guide[at]), _N_GUIDE_OCTAVES - 1) if guide.shape[0] > 0 else 0
        active = cls * _N_ACTIVITY + activity_octave
        mixed = _ACTIVITY + active * _N_GUIDE_OCTAVES + guided if cls != _APPROXIMATION else -(1 << 40)
        weights = _MIX + (cls * 3 + min(near, 2)) * N_INPUTS
        step = N_CLASSES * _N_ACTIVITY * _N_GUIDE_OCTAVES  # the next decision's activity contexts
        step_weights = N_CLASSES * 3 * N_INPUTS
        if hints.shape[0]:
            fine = _bandelet_significance(cls, ctx, hints[i])
            if hints[i] & SQUARE_START:
                agree = 0
        else:
            fine = _SIG + cls * _N_SUM * 3 * _N_GUIDE + ctx
        significant, r = code_mixed(
            r, buf, probs, counts, fine, _SIG_COARSE + ctx, mixed, weights, 1 if m > 0 else 0, decoding
        )
        if significant == 0:
            m = 0
        else:
            near5 = min(near, 4) * _N_GUIDE + g
            fine = cls * 5 * _N_GUIDE + near5
            above, r = code_mixed(
                r,
                buf,
                probs,
                counts,
                _GT1 + fine,
                _GT1_COARSE + near5,
                mixed + step,
                weights + step_weights,
                1 if m > 1 else 0,
                decoding,
            )
            if above:
                above, r = code_mixed(
                    r,
                    buf,
                    probs,
                    counts,
                    _GT2 + fine,
                    _GT2_COARSE + near5,
                    mixed + 2 * step,
                    weights + 2 * step_weights,
                    1 if m > 2 else 0,
                    decoding,
                )
                if above:
                    rest, r = elias_gamma(
                        r,
                        buf,
                        probs,
                        counts,
                        m - 2,
                        _PREFIX_ACTIVE + active * EG_PREFIX if mixed >= 0 else _PREFIX,
                        decoding,
                        _PREFIX + cls * EG_PREFIX if mixed >= 0 else _PREFIX_COARSE,
                        _FIRST_BELOW + active * EG_PREFIX if mixed >= 0 else -1,
                        _FIRST_BELOW_COARSE + cls * EG_PREFIX,
                    )
                    if rest < 0 or rest > MAX_MAGNITUDE:
                        status = -1
                        break
                    m = rest + 2
                else:
                    m = 2
            else:
                m = 1
            leader = guide[at] if guide.shape[0] > 0 else 0
            sign_ctx, fine = _sign_contexts(known, neighbours[i], cls, leader, agree, hints.shape[0] > 0)
            negative, r = code_backed(
                r, buf, probs, counts, fine, _SIGN_COARSE + sign_ctx, 1 if value < 0 else 0, decoding
            )
            if negative:
                m = -m
            if leader != 0:
                agree += 1 if (leader < 0) == (negative == 1) else -1
        known[at] = predicted + m
        if decoding:
            if abs(known[at]) > MAX_MAGNITUDE:
                status = -1
                break
            q[at] = known[at]
        else:
            spent[at] = (r[SPENT] - before) / COST_SCALE
    keep_registers(st, r)
    return status


@njit(cache=True, nogil=True, inline="always")
def _sign_contexts(known, neighbours, cls, leader, agree, bandelet):
    """The sign's coarse context (the signs of the left and upper neighbours, and of the guide
    ``leader``) and its fine one: of a 1D bandelet coefficient (``bandelet``,
    :func:`_bandelet_sign`), else of its class."""
    j = neighbours[0]
    sign_ctx = 0 if j < 0 or known[j] == 0 else (1 if known[j] > 0 else 2)
    j = neighbours[1]
    sign_ctx += 0 if j < 0 or known[j] == 0 else (9 if known[j] > 0 else 18)
    if bandelet:
        return _bandelet_sign(cls, sign_ctx, leader, agree)
    if leader != 0:
        sign_ctx += 3 if leader > 0 else 6
    return sign_ctx, _SIGN + cls * _N_SIGN + sign_ctx


@njit(cache=True, nogil=True, inline="always")
def _full(known, j):
    """The full magnitude of the coefficient at ``j`` (0 for ``j < 0``)."""
    return abs(known[j]) if j >= 0 else 0


@njit(cache=True, nogil=True, inline="always")
def _bandelet_significance(cls, ctx, hint):
    """Significance context of a 1D bandelet coefficient: its class and the contexts of every
    class (neighbours, parent, guide), refined by the ``hint`` read around its square."""
    fine = (cls - _FIRST_BANDELET) * _N_SUM * 3 * _N_GUIDE + ctx
    return _BSIG + fine * N_HINTS + (hint & (SQUARE_START - 1))


@njit(cache=True, nogil=True, inline="always")
def _bandelet_sign(cls, sign_ctx, leader, agree):
    """Sign context of a 1D bandelet coefficient: the signs of its two 1D neighbours
    (``sign_ctx`` < 9 + 18) and the guide channel's sign ``leader``, flipped when the signs coded
    so far in the square mostly disagreed with the guide's (``agree`` < 0: across a crease the
    two channels of a normal map change together, in a proportion of either sign). Returns the
    shared context (< :data:`_N_SIGN`) and the class's own."""
    if leader != 0:
        sign_ctx += 3 if (leader > 0) == (agree >= 0) else 6
    return sign_ctx, _BSIGN + (cls - _FIRST_BANDELET) * 2 * _N_SIGN + sign_ctx + (
        _N_SIGN if agree != 0 else 0
    )


def coefficient_contexts() -> int:
    """Size of the context table of the coefficient stream."""
    return _N_COEFF_CONTEXTS


def code_coefficients(
    coder: Coder,
    q: np.ndarray,
    plan,
    known: np.ndarray,
    guide: np.ndarray,
    spent: np.ndarray,
    hints: np.ndarray | None = None,
) -> None:
    """Code the quantized coefficients ``plan.order`` of one channel.

    Parameters
    ----------
    coder : Coder
        A coder made with :func:`coefficient_contexts` contexts.
    q : ndarray of int32, shape (H * W,)
        Signed bin indices, raveled Mallat layout. Filled in when decoding (pass zeros).
    plan : bandelets.coding.order.Segment
        Coding order, context class and neighbour positions of the coefficients.
    known : ndarray of int64, shape (H * W,)
        What the context models see: the values coded so far (zeros elsewhere). Updated.
    guide : ndarray of int, shape (H * W,) or (0,)
        What the previous channel coded (bandelet coefficients in its bandelet squares), whose
        magnitude at the same position is a context (the channels of a normal map or a
        geometry image change at the same places); empty for the first channel.
    spent : ndarray of float64, shape (H * W,)
        Receives the ideal code length of each coefficient encoded, in bits (what the rate
        model of :mod:`bandelets.search.lagrangian` is fitted to); left alone when decoding.
    hints : ndarray of int64, shape (n,), optional
        For a segment of bandelet squares: :func:`bandelets.coding.squarecontexts.square_hints`,
        which selects the bandelet classes' own significance and sign contexts.
    """
    if not coder.decoding:
        bits = np.abs(q[plan.order]).astype(np.int64)
        nonzero = bits > 0
        lengths = np.zeros(bits.shape, np.int64)
        lengths[nonzero] = np.floor(np.log2(bits[nonzero])).astype(np.int64)
        coder.reserve(int(bits.shape[0] + np.sum(nonzero) * 6 + 2 * lengths.sum()) * 12 // 8 + 64)
    status = _coefficients(
        coder.state,
        coder.buf,
        coder.probs,
        coder.counts,
        q,
        known,
        guide,
        spent,
        plan.order,
        plan.classes,
        plan.neighbours,
        _NO_HINTS if hints is None else hints,
        coder.decoding,
    )
    if status != 0:
        raise CorruptStream("coded coefficient stream is corrupt")
    coder.check()  # fail at the first run past the end, not after a whole image of zeros
