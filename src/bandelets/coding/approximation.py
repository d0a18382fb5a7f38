"""Entropy coding of the coarse approximation: the residual of a spatial prediction, in contexts
of its own (format version 18).

The approximation of a channel is a small image of bins, smooth where the surface is and with
jumps at its creases, coded before any detail. Each bin is predicted by the median edge detector
of LOCO-I (left or up at an edge, the plane through left, up and up-left elsewhere) and the
residual is coded with the decisions of :func:`bandelets.coding.coefficients.code_coefficients` (zero, above
1, above 2, an Elias-gamma rest, a sign), in contexts read where the residuals cluster:

* the fine context of a decision is the octave of the local gradient of the bins
  (``|left - corner| + |up - corner| + |right - up|``, up to 7) and the guide's residual
  magnitude at the same place (0, 1, 2+, or no guide: the channel coded before, whose residual,
  predicted the same way, is large where this one's is, at the creases a normal map's channels
  share); it is backed by the gradient's octave alone;
* a third, mixed in (:func:`bandelets.coding.rangecoder.code_mixed`), reads the octave of the residuals'
  magnitudes at left, up, up-left and up-right plus half the gradient, and the octave of the
  guide's residual;
* the sign reads the signs of the residuals at left and up and of the guide's.

Version 17 coded these residuals as detail coefficients of class 0, in contexts of the bins'
own magnitudes (clipped at 2: saturated wherever the surface is not flat) and of the guide's bin
rather than its residual. On the maps coded with few levels, whose approximation is a large part
of the file (the fandisk and the bunny rendered from the top at 256, fandisk's normal map:
16 to 57 % of the coefficient stream at 0.25 to 2 bpp), the same bins take 4 to 14 % fewer bytes
(``benchmarks/approximation_bytes.py``); on the maps of many levels (an approximation of a few
dozen bytes) 0 to 4 bytes more. Tried and
lost (bytes of the same bins, script not kept): the neighbours' clipped residual sum as the fine
context instead of the gradient (a third of the gain); the guide's residual at left and up in
the mixed context (nothing); a prediction of the residual from the guide's, by the ratio of the
two channels' residuals at the four neighbours (+0.3 % of the file on bunny's normal map, -0.1
to -0.2 % on fandisk's); the lossless coder's model (:mod:`bandelets.coding.lossless`, with or without
its blend of predictors: 5 to 40 % more than this one on these small images, too many contexts
to learn from a few thousand bins).

Why written here: the context model is the project's, compiled with numba with its coder as
:mod:`bandelets.coding.rangecoder` explains.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .coefficients import MAX_MAGNITUDE, coefficient_contexts, median_of, median_prediction, neighbourhood
from .rangecoder import (
    COST_SCALE,
    SPENT,
    Coder,
    CorruptStream,
    code_backed,
    code_mixed,
    elias_gamma,
    keep_registers,
    octave,
    registers,
)

__all__ = ["N_CONTEXTS", "code_approximation"]

_N_GRADIENT = 8  # octaves of the local gradient: the fine and the coarse contexts
_N_GUIDE = 4  # the guide's residual magnitude: 0, 1, 2+, or no guide
_N_ACTIVITY = 12
_N_GUIDE_OCTAVES = 6
_PREFIX = 20
_FINE = coefficient_contexts()  # after the detail coefficients' contexts, in the same table
_COARSE = _FINE + 3 * _N_GRADIENT * _N_GUIDE
_MIXED = _COARSE + 3 * _N_GRADIENT
_WEIGHTS = _MIXED + 3 * _N_ACTIVITY * _N_GUIDE_OCTAVES  # one pair per decision x gradient 0, 1, 2+
_RESTS = _WEIGHTS + 3 * 3 * 2
_RESTS_COARSE = _RESTS + _N_ACTIVITY * _PREFIX
_FIRST_BELOW = _RESTS_COARSE + _PREFIX
_FIRST_BELOW_COARSE = _FIRST_BELOW + _N_ACTIVITY * _PREFIX
_SIGNS = _FIRST_BELOW_COARSE + _PREFIX  # 27, then the 9 without the guide's sign
#: Size of the coefficient stream's context table: the details' contexts, then these.
N_CONTEXTS = _SIGNS + 27 + 9

_kernel = njit(cache=True, nogil=True, _nrt=False)


# One kernel for both sides, ``decoding`` read at run time: the approximation is at most a
# sixteenth of the bins, where the detail coder's two constant-folded copies save 8 %.
@_kernel
def _approximation(
    st, buf, probs, counts, q, known, guide, spent, order, positions, residuals, width, decoding
):
    r = registers(st)
    status = 0
    guided = guide.shape[0] > 0
    for i in range(order.shape[0]):
        at = order[i]
        here = positions[i]
        before = r[SPENT]
        left, up, corner, right = neighbourhood(known, here)
        predicted = median_of(left, up, corner)
        gradient = abs(left - corner) + abs(up - corner) + abs(right - up)
        rl = residuals[i - 1] if here[0] >= 0 else 0
        ru = residuals[i - width] if here[1] >= 0 else 0
        rc = residuals[i - width - 1] if here[2] >= 0 else 0
        rr = residuals[i - width + 1] if here[3] >= 0 else 0
        lead = guide[at] - median_prediction(guide, here) if guided else 0
        near = octave(gradient, _N_GRADIENT - 1)
        ctx = near * _N_GUIDE + (min(abs(lead), 2) if guided else 3)
        activity = octave(2 * abs(rl) + 2 * abs(ru) + abs(rc) + abs(rr) + gradient // 2, _N_ACTIVITY - 1)
        led = octave(2 * abs(lead), _N_GUIDE_OCTAVES - 1) if guided else 0
        mixed = _MIXED + activity * _N_GUIDE_OCTAVES + led
        weights = _WEIGHTS + min(near, 2) * 2
        value = q[at] - predicted
        m = abs(value)
        bit = 1 if m > 0 else 0
        for decision in range(3):
            bit, r = code_mixed(
                r,
                buf,
                probs,
                counts,
                _FINE + decision * _N_GRADIENT * _N_GUIDE + ctx,
                _COARSE + decision * _N_GRADIENT + near,
                mixed + decision * _N_ACTIVITY * _N_GUIDE_OCTAVES,
                weights + decision * 6,
                bit,
                decoding,
            )
            if bit == 0:
                m = decision
                break
            bit = 1 if m > decision + 1 else 0
        else:
            rest, r = elias_gamma(
                r,
                buf,
                probs,
                counts,
                m - 2,
                _RESTS + activity * _PREFIX,
                decoding,
                np.int64(_RESTS_COARSE),  # int64, not literals: rangecoder._positive's specialization
                _FIRST_BELOW + activity * _PREFIX,
                np.int64(_FIRST_BELOW_COARSE),
            )
            if rest < 0 or rest > MAX_MAGNITUDE:
                status = -1
                break
            m = rest + 2
        if m > 0:
            signs = (0 if rl == 0 else (1 if rl > 0 else 2)) + (0 if ru == 0 else (3 if ru > 0 else 6))
            fine = signs + (0 if lead == 0 else (9 if lead > 0 else 18))
            negative, r = code_backed(
                r, buf, probs, counts, _SIGNS + fine, _SIGNS + 27 + signs, 1 if value < 0 else 0, decoding
            )
            if negative:
                m = -m
        residuals[i] = m
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


def code_approximation(
    coder: Coder, q: np.ndarray, plan, known: np.ndarray, guide: np.ndarray, spent: np.ndarray
) -> None:
    """Code the approximation ``plan`` (:func:`bandelets.coding.order.approximation_plan`) of one
    channel, as :func:`bandelets.coding.coefficients.code_coefficients` codes details (the same arguments:
    ``q`` filled in when decoding, ``known`` updated, ``spent`` the ideal code lengths, ``guide``
    the channel coded before or empty), with a coder of :data:`N_CONTEXTS` contexts."""
    n = plan.order.shape[0]
    # The plan is a raster of the approximation's box; its first row has no upper neighbours.
    width = int(np.count_nonzero(plan.neighbours[:, 1] < 0))
    if not coder.decoding:
        # At most 11 bits a decision: three, a sign, and an Elias-gamma rest of a residual at
        # most twice the largest bin.
        most = 2 * int(np.max(np.abs(q[plan.order]), initial=0)) + 1
        coder.reserve(n * (4 + 2 * most.bit_length()) * 11 // 8 + 64)
    status = _approximation(
        coder.state,
        coder.buf,
        coder.probs,
        coder.counts,
        q,
        known,
        guide,
        spent,
        plan.order,
        plan.neighbours,
        np.zeros(n, np.int64),
        width,
        coder.decoding,
    )
    if status != 0:
        raise CorruptStream("coded approximation stream is corrupt")
    coder.check()
