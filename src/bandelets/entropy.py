"""Entropy coding: an adaptive binary range coder and the context models it is driven by.

Why written here: the coder makes one context-dependent binary decision per coefficient
(significance from the neighbours, parent and guide channel already decoded, then
magnitude and sign), millions of them per image, with contexts computed from what was
just decoded. A library coder must then be called from Python once per decision:
``constriction``'s range coder, the best-kept candidate, costs about 3 us per decision
that way; it matches this coder's speed (about 40 ns per decision) only when called once
on a whole array with probabilities fixed in advance, which rules out adapting them to
what was just decoded (``benchmarks/entropy_coder.py``, 10**6 decisions). So the coder is
compiled with numba together with its context modelling.
The coder is the carry-less range coder of LZMA (a 32-bit range, carries propagated
through a cached byte) with 16-bit probabilities whose adaptation rate starts fast and
slows to 1/128 as a context matures.

The coefficient contexts (:func:`code_coefficients`) are many (class x neighbours x guide) and a
256 x 256 map at 0.25 bpp uses about 1,500 of them a few times each: learning each one from 1/2
cost about a sixth of such a file. So each of them is backed by the same context shared by all
the classes, which it outweighs as it is used
(:func:`_code_backed`): +0.3 dB BD-PSNR on the crease map, +0.1 to +0.2 on the others
(BENCHMARKS, "Context modelling of format version 9"). The 1D coefficients of the bandelet
squares have significance and sign contexts of their own, refined by what
:mod:`bandelets.squarecontexts` reads around their square (format version 10).

The same functions encode and decode: each takes a ``decoding`` flag, so the context
modelling, the only delicate part, is written once and cannot drift between the two sides.

A coder state is a small int64 array plus its byte buffer and its context tables; see
:class:`Coder`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "Coder",
    "CorruptStream",
    "N_CLASSES",
    "N_HINTS",
    "SQUARE_START",
    "code_flags",
    "code_positive",
    "code_symbols",
    "code_coefficients",
]


class CorruptStream(ValueError):
    """A coded stream does not decode to anything valid."""


_TOP = np.int64(1 << 24)
_PROB_BITS = 16
_PROB_ONE = 1 << _PROB_BITS
_PROB_MIN = 32
_MAX_SHIFT = 7
_SHIFT = np.minimum(np.floor(np.log2(np.arange(2, 130))), _MAX_SHIFT).astype(np.int64)
# State slots (encoder: low, range, cache, cache_size, pos; decoder: code, range, -, -, pos,
# overrun), then the ideal code length spent so far, in 1/65536 bit.
_LOW, _RANGE, _CACHE, _CACHE_SIZE, _POS, _OVERRUN, _SPENT = range(7)
_COST_SCALE = 65536.0
# -log2 of a probability, tabulated on 12 bits: the ledger of what each decision costs.
_COST = np.rint(-np.log2((np.arange(4096) + 0.5) / 4096) * _COST_SCALE).astype(np.int64)

#: Coefficient context classes: 0 approximation, 1-15 wavelet (orientation x level 1 to 5+),
#: 16-30 bandelet (square width 4, 8, 16+ x 1D scale bucket).
N_CLASSES = 31
_N_SUM = 8
_SUM_BUCKET = np.array([0, 1, 2, 3, 4, 5, 5, 6, 6, 6, 7, 7, 7, 7, 7], np.int64)
_EG_PREFIX = 20
_MAX_PREFIX = 31
# Context table layout of the coefficient stream.
_APPROXIMATION = 0
#: Largest magnitude a decoded coefficient may have (the quantizer's MAX_INDEX).
MAX_MAGNITUDE = 2**30
_N_GUIDE = 4  # the guide channel's magnitude at the same place: 0, 1, 2+, or no guide
_SIG = 0
_GT1 = _SIG + N_CLASSES * _N_SUM * 3 * _N_GUIDE
_GT2 = _GT1 + N_CLASSES * 5 * _N_GUIDE
_PREFIX = _GT2 + N_CLASSES * 5 * _N_GUIDE
_SIGN = _PREFIX + N_CLASSES * _EG_PREFIX
# The coarse contexts that back them (:func:`_code_backed`): the same contexts without the class.
_SIG_COARSE = _SIGN + N_CLASSES * 27
_GT1_COARSE = _SIG_COARSE + _N_SUM * 3 * _N_GUIDE
_GT2_COARSE = _GT1_COARSE + 5 * _N_GUIDE
_SIGN_COARSE = _GT2_COARSE + 5 * _N_GUIDE
_PREFIX_COARSE = _SIGN_COARSE + 27
# The bandelet classes' own significance and sign contexts (:func:`_bandelet_significance`,
# :func:`_bandelet_sign`), backed by the same coarse ones.
_FIRST_BANDELET = 16
#: Number of hints a bandelet coefficient's significance context adds
#: (:func:`bandelets.squarecontexts.square_hints`), and the flag of a square's first coefficient.
N_HINTS = 24
SQUARE_START = 1 << 8
_BSIG = _PREFIX_COARSE + _EG_PREFIX
_BSIGN = _BSIG + (N_CLASSES - _FIRST_BANDELET) * _N_SUM * 3 * _N_GUIDE * N_HINTS
_N_COEFF_CONTEXTS = _BSIGN + (N_CLASSES - _FIRST_BANDELET) * 54
_BACKOFF = 4
_MATURE = _SHIFT.shape[0] - 1  # the count at which a context stops counting


class Coder:
    """State of one range-coded stream: coder registers, bytes, adaptive contexts.

    Parameters
    ----------
    n_contexts : int
        Size of the context table.
    data : bytes, optional
        The stream to decode; omit to encode.
    capacity : int
        Encoder buffer size in bytes; grown by :meth:`reserve`.
    """

    def __init__(self, n_contexts: int, data: bytes | None = None, capacity: int = 1 << 16):
        self.decoding = data is not None
        self.probs = np.full(n_contexts, _PROB_ONE // 2, np.int64)
        self.counts = np.zeros(n_contexts, np.int64)
        self.state = np.zeros(7, np.int64)
        if self.decoding:
            self.buf = np.frombuffer(bytes(data), np.uint8).copy()
            _decoder_start(self.state, self.buf)
        else:
            self.buf = np.zeros(capacity, np.uint8)
            self.state[_RANGE] = 0xFFFFFFFF
            self.state[_CACHE_SIZE] = 1

    def reserve(self, n_bytes: int) -> None:
        """Make sure the encoder can write ``n_bytes`` more bytes."""
        need = int(self.state[_POS]) + n_bytes + 16
        if not self.decoding and need > self.buf.shape[0]:
            grown = np.zeros(max(need, 2 * self.buf.shape[0]), np.uint8)
            grown[: self.buf.shape[0]] = self.buf
            self.buf = grown

    def finish(self) -> bytes:
        """Flush the encoder and return the stream."""
        self.reserve(8)
        _encoder_flush(self.state, self.buf)
        # The first byte of this coder's output is always the initial zero cache: not stored.
        return self.buf[1 : self.state[_POS]].tobytes()

    def check(self) -> None:
        """Raise :class:`CorruptStream` if the decoder ran past the end of its stream."""
        if self.decoding and self.state[_OVERRUN] > 4:
            raise CorruptStream("coded stream is truncated or corrupt")


@njit(cache=True, nogil=True)
def _shift_low(st, buf):
    low = st[_LOW]
    if low < 0xFF000000 or low > 0xFFFFFFFF:
        carry = low >> 32
        temp = st[_CACHE]
        while True:
            buf[st[_POS]] = (temp + carry) & 0xFF
            st[_POS] += 1
            temp = 0xFF
            st[_CACHE_SIZE] -= 1
            if st[_CACHE_SIZE] == 0:
                break
        st[_CACHE] = (low >> 24) & 0xFF
    st[_CACHE_SIZE] += 1
    st[_LOW] = (low & 0x00FFFFFF) << 8


@njit(cache=True, nogil=True)
def _encoder_flush(st, buf):
    for _ in range(5):
        _shift_low(st, buf)


@njit(cache=True, nogil=True)
def _next_byte(st, buf):
    pos = st[_POS]
    st[_POS] = pos + 1
    if pos < buf.shape[0]:
        return np.int64(buf[pos])
    st[_OVERRUN] += 1
    return np.int64(0)


@njit(cache=True, nogil=True)
def _decoder_start(st, buf):
    st[_RANGE] = 0xFFFFFFFF
    code = np.int64(0)
    for _ in range(4):
        code = (code << 8) | _next_byte(st, buf)
    st[_LOW] = code


@njit(cache=True, nogil=True, inline="always")
def _code_at(st, buf, p, bit, decoding):
    """Code one binary decision whose 1 has probability ``p`` (of ``_PROB_ONE``); returns the bit."""
    bound = (st[_RANGE] >> _PROB_BITS) * p
    if decoding:
        bit = 1 if st[_LOW] < bound else 0
    st[_SPENT] += _COST[(p if bit else _PROB_ONE - p) >> 4]
    if bit:
        st[_RANGE] = bound
    else:
        if not decoding:
            st[_LOW] += bound
        else:
            st[_LOW] -= bound
        st[_RANGE] -= bound
    while st[_RANGE] < _TOP:
        st[_RANGE] <<= 8
        if decoding:
            st[_LOW] = ((st[_LOW] << 8) | _next_byte(st, buf)) & 0xFFFFFFFF
        else:
            _shift_low(st, buf)
    return bit


@njit(cache=True, nogil=True, inline="always")
def _adapt(probs, counts, ctx, bit):
    """Move the probability of context ``ctx`` towards ``bit``."""
    # Adaptation rate about 1/(n + 2) for the n-th use of a context (a counting
    # estimator while the context is young), then a window of about 128 decisions.
    p = probs[ctx]
    n = counts[ctx]
    shift = _SHIFT[n]
    if n < _SHIFT.shape[0] - 1:
        counts[ctx] = n + 1
    if bit:
        p += (_PROB_ONE - p) >> shift
    else:
        p -= p >> shift
    probs[ctx] = min(max(p, _PROB_MIN), _PROB_ONE - _PROB_MIN)


@njit(cache=True, nogil=True, inline="always")
def _code_bit(st, buf, probs, counts, ctx, bit, decoding):
    """Code one binary decision in context ``ctx``; returns the bit (decoded or given)."""
    bit = _code_at(st, buf, probs[ctx], bit, decoding)
    if counts is not None:
        _adapt(probs, counts, ctx, bit)
    return bit


@njit(cache=True, nogil=True, inline="always")
def _code_backed(st, buf, probs, counts, ctx, coarse, bit, decoding):
    """Code one binary decision in context ``ctx`` backed by the ``coarse`` context that it
    refines: while ``ctx`` has been used ``n`` times, its probability is weighted ``n`` against
    ``_BACKOFF`` for the coarse one, so that a rarely used context starts from what its
    neighbours in the table learned instead of from 1/2. Both adapt, until ``ctx`` is mature."""
    n = counts[ctx]
    if n == _MATURE:  # the coarse context's weight would be 3 %: left out, for speed
        return _code_bit(st, buf, probs, counts, ctx, bit, decoding)
    p = (n * probs[ctx] + _BACKOFF * probs[coarse]) // (n + _BACKOFF)
    bit = _code_at(st, buf, p, bit, decoding)
    _adapt(probs, counts, ctx, bit)
    _adapt(probs, counts, coarse, bit)
    return bit


_EQUIPROBABLE = np.array([_PROB_ONE // 2], np.int64)
_NO_HINTS = np.zeros(0, np.int64)


@njit(cache=True, nogil=True, inline="always")
def _code_raw_bit(st, buf, bit, decoding, half):
    return _code_bit(st, buf, half, None, 0, bit, decoding)


@njit(cache=True, nogil=True)
def _flags(st, buf, probs, counts, bits, ctxs, decoding):
    for i in range(bits.shape[0]):
        bits[i] = _code_bit(st, buf, probs, counts, ctxs[i], bits[i], decoding)


def code_flags(coder: Coder, bits: np.ndarray, ctxs: np.ndarray) -> np.ndarray:
    """Code binary flags, each in its context.

    Parameters
    ----------
    coder : Coder
    bits : ndarray of int64, shape (n,)
        The flags to encode (ignored when decoding: pass zeros of the right length).
    ctxs : ndarray of int64, shape (n,)
        Context index of each flag.

    Returns
    -------
    ndarray of int64, shape (n,): the flags (decoded when decoding).
    """
    bits = np.array(bits, np.int64)
    coder.reserve(2 * bits.shape[0])
    _flags(
        coder.state, coder.buf, coder.probs, coder.counts, bits, np.asarray(ctxs, np.int64), coder.decoding
    )
    return bits


@njit(cache=True, nogil=True)
def _symbols(st, buf, probs, counts, symbols, bases, n_bits, decoding):
    for i in range(symbols.shape[0]):
        # Binary tree over n_bits bits, most significant first: node contexts 1 .. 2**n_bits - 1.
        node = 1
        value = symbols[i]
        for b in range(n_bits[i] - 1, -1, -1):
            bit = _code_bit(st, buf, probs, counts, bases[i] + node, (value >> b) & 1, decoding)
            node = 2 * node + bit
        symbols[i] = node - (1 << n_bits[i])


def code_symbols(coder: Coder, symbols: np.ndarray, bases: np.ndarray, n_bits: np.ndarray) -> np.ndarray:
    """Code integers ``0 <= s < 2**n_bits`` with an adaptive model per ``base``.

    Each symbol is a path in a binary tree whose nodes are contexts ``base + 1 ..
    base + 2**n_bits - 1``: an adaptive multi-symbol model with one context per node.
    Returns the symbols (decoded when decoding).
    """
    symbols = np.array(symbols, np.int64)
    coder.reserve(2 * int(np.sum(n_bits)) + 16)
    _symbols(
        coder.state,
        coder.buf,
        coder.probs,
        coder.counts,
        symbols,
        np.asarray(bases, np.int64),
        np.asarray(n_bits, np.int64),
        coder.decoding,
    )
    return symbols


@njit(cache=True, nogil=True)
def _elias_gamma(st, buf, probs, counts, half, r, base, decoding, coarse=-1):
    """Code ``r >= 1``: adaptive unary prefix ``floor(log2 r)`` (contexts ``base + i``), then
    its low bits equiprobable. Returns ``r`` (decoded when decoding), -1 if corrupt."""
    n_prefix = 0
    while (r >> (n_prefix + 1)) > 0:
        n_prefix += 1
    e = 0
    while True:
        ctx = base + min(e, _EG_PREFIX - 1)
        bit = 1 if e < n_prefix else 0
        if coarse >= 0:
            bit = _code_backed(st, buf, probs, counts, ctx, coarse + min(e, _EG_PREFIX - 1), bit, decoding)
        else:
            bit = _code_bit(st, buf, probs, counts, ctx, bit, decoding)
        if bit == 0:
            break
        e += 1
        if e > _MAX_PREFIX:
            return -1
    value = 1
    for b in range(e - 1, -1, -1):
        value = 2 * value + _code_raw_bit(st, buf, (r >> b) & 1, decoding, half)
    return value


@njit(cache=True, nogil=True)
def _positive(st, buf, probs, counts, half, values, bases, decoding):
    for i in range(values.shape[0]):
        values[i] = _elias_gamma(st, buf, probs, counts, half, values[i], bases[i], decoding)
        if values[i] < 0:
            return -1
    return 0


def code_positive(coder: Coder, values: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """Code integers ``>= 1`` (Elias-gamma with an adaptive prefix in contexts ``base + 0..19``).

    Returns the values (decoded when decoding; pass ones).
    """
    values = np.array(values, np.int64)
    coder.reserve(8 * values.shape[0] + 16)
    if (
        _positive(
            coder.state,
            coder.buf,
            coder.probs,
            coder.counts,
            _EQUIPROBABLE.copy(),
            values,
            np.asarray(bases, np.int64),
            coder.decoding,
        )
        != 0
    ):
        raise CorruptStream("coded integer stream is corrupt")
    return values


@njit(cache=True, nogil=True)
def _coefficients(
    st, buf, probs, counts, half, q, known, guide, spent, order, classes, neighbours, hints, decoding
):
    mags = np.zeros(5, np.int64)
    agree = 0  # in a bandelet square: signs equal to the guide's so far, minus those opposite
    for i in range(order.shape[0]):
        at = order[i]
        before = st[_SPENT]
        cls = classes[i]
        for k in range(5):
            j = neighbours[i, k]
            mags[k] = min(abs(known[j]), 2) if j >= 0 else 0
        j = neighbours[i, 5]
        total = 2 * mags[0] + 2 * mags[1] + mags[2] + mags[3] + (min(abs(known[j]), 2) if j >= 0 else 0)
        near = _SUM_BUCKET[total]
        # The approximation is smooth: code its residual from the median predictor of
        # LOCO-I (left, up, up-left); details are coded as they are.
        predicted = _median_prediction(known, neighbours[i]) if cls == _APPROXIMATION else 0
        value = q[at] - predicted
        m = abs(value)
        g = min(abs(guide[at]), 2) if guide.shape[0] > 0 else 3
        ctx = (near * 3 + mags[4]) * _N_GUIDE + g
        if hints.shape[0]:
            fine = _bandelet_significance(cls, ctx, hints[i])
            if hints[i] & SQUARE_START:
                agree = 0
        else:
            fine = _SIG + cls * _N_SUM * 3 * _N_GUIDE + ctx
        if _code_backed(st, buf, probs, counts, fine, _SIG_COARSE + ctx, 1 if m > 0 else 0, decoding) == 0:
            m = 0
        else:
            near5 = min(near, 4) * _N_GUIDE + g
            fine = cls * 5 * _N_GUIDE + near5
            if _code_backed(
                st, buf, probs, counts, _GT1 + fine, _GT1_COARSE + near5, 1 if m > 1 else 0, decoding
            ):
                if _code_backed(
                    st, buf, probs, counts, _GT2 + fine, _GT2_COARSE + near5, 1 if m > 2 else 0, decoding
                ):
                    r = _elias_gamma(
                        st,
                        buf,
                        probs,
                        counts,
                        half,
                        m - 2,
                        _PREFIX + cls * _EG_PREFIX,
                        decoding,
                        _PREFIX_COARSE,
                    )
                    if r < 0 or r > MAX_MAGNITUDE:
                        return -1
                    m = r + 2
                else:
                    m = 2
            else:
                m = 1
            j = neighbours[i, 0]
            sign_ctx = 0 if j < 0 or known[j] == 0 else (1 if known[j] > 0 else 2)
            j = neighbours[i, 1]
            sign_ctx += 0 if j < 0 or known[j] == 0 else (9 if known[j] > 0 else 18)
            leader = guide[at] if guide.shape[0] > 0 else 0
            if hints.shape[0]:
                sign_ctx, fine = _bandelet_sign(cls, sign_ctx, leader, agree)
            else:
                if leader != 0:
                    sign_ctx += 3 if leader > 0 else 6
                fine = _SIGN + cls * 27 + sign_ctx
            negative = _code_backed(
                st, buf, probs, counts, fine, _SIGN_COARSE + sign_ctx, 1 if value < 0 else 0, decoding
            )
            if negative:
                m = -m
            if leader != 0:
                agree += 1 if (leader < 0) == (negative == 1) else -1
        known[at] = predicted + m
        spent[at] = (st[_SPENT] - before) / _COST_SCALE
        if decoding:
            if abs(known[at]) > MAX_MAGNITUDE:
                return -1
            q[at] = known[at]
    return 0


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
    shared context (< 27) and the class's own."""
    if leader != 0:
        sign_ctx += 3 if (leader > 0) == (agree >= 0) else 6
    return sign_ctx, _BSIGN + (cls - _FIRST_BANDELET) * 54 + sign_ctx + (27 if agree != 0 else 0)


@njit(cache=True, nogil=True, inline="always")
def _median_prediction(known, neighbours):
    left = known[neighbours[0]] if neighbours[0] >= 0 else 0
    up = known[neighbours[1]] if neighbours[1] >= 0 else left
    if neighbours[0] < 0:
        left = up
    corner = known[neighbours[2]] if neighbours[2] >= 0 else up
    if corner >= max(left, up):
        return min(left, up)
    if corner <= min(left, up):
        return max(left, up)
    return left + up - corner


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
    plan : bandelets.layout.Segment
        Coding order, context class and neighbour positions of the coefficients.
    known : ndarray of int64, shape (H * W,)
        What the context models see: the values coded so far (zeros elsewhere). Updated.
    guide : ndarray of int, shape (H * W,) or (0,)
        What the previous channel coded (bandelet coefficients in its bandelet squares), whose
        magnitude at the same position is a context (the channels of a normal map or a
        geometry image change at the same places); empty for the first channel.
    spent : ndarray of float64, shape (H * W,)
        Receives the ideal code length of each coefficient coded, in bits (what the rate
        model of :mod:`bandelets.lagrangian` is fitted to).
    hints : ndarray of int64, shape (n,), optional
        For a segment of bandelet squares: :func:`bandelets.squarecontexts.square_hints`,
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
        _EQUIPROBABLE.copy(),
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
