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
:mod:`bandelets.coding.squarecontexts` reads around their square (format version 10).

Those contexts see the neighbours' magnitudes clipped at 2. Since format version 16 the
significance and the first two magnitude decisions of a detail coefficient also read an
*activity* context (its class, the octave of its neighbours' and parent's full magnitudes, the
octave of the guide's), whose probability is mixed with the backed one in the logistic domain
by weights learned as the stream goes (:func:`_code_mixed`, a two-input mixer after PAQ's), and
the Elias-gamma prefix of the larger magnitudes and the first bit below its leading one are
read in contexts of that activity: the coefficient streams of the maps of issue 15 are 1 to 2 %
shorter at the same threshold (BENCHMARKS, "Mixed contexts"), for about 10 ms more to decode
the 512 x 512 crease map at 1 bpp (entropy decoding 33 ms instead of 22).

The same functions encode and decode: each takes a ``decoding`` flag, so the context
modelling, the only delicate part, is written once and cannot drift between the two sides.

A coder state is a small int64 array plus its byte buffer and its context tables; see
:class:`Coder`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "Coder",
    "CorruptStream",
    "N_CLASSES",
    "N_HINTS",
    "SQUARE_START",
    "code_flags",
    "code_flag_map",
    "code_positive",
    "code_symbols",
    "code_coefficients",
    "code_bit",
    "code_backed",
    "code_mixed",
    "median_of",
    "median_prediction",
    "neighbourhood",
    "elias_gamma",
    "code_raw_bit",
    "octave",
    "registers",
    "keep_registers",
    "POSITION",
    "SPENT",
    "COST_SCALE",
]


class CorruptStream(ValueError):
    """A coded stream does not decode to anything valid."""


_TOP = np.int64(1 << 24)
_PROB_BITS = 16
_PROB_ONE = 1 << _PROB_BITS
_PROB_MIN = 32
_MAX_SHIFT = 7
_SHIFT = np.minimum(np.floor(np.log2(np.arange(2, 130))), _MAX_SHIFT).astype(np.int64)
# State slots (encoder: low, range, cache, cache_size, pos; decoder: code, range, -, -, pos, which
# runs past the end of a truncated stream), then the ideal code length the encoder spent so far,
# in 1/65536 bit.
_LOW, _RANGE, _CACHE, _CACHE_SIZE, _POS, _SPENT = range(6)
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
# Context table layout of the coefficient stream. Class 0 is the approximation, which files code
# with :mod:`bandelets.coding.approximation` in contexts of its own after these (format version 18).
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
#: (:func:`bandelets.coding.squarecontexts.square_hints`), and the flag of a square's first coefficient.
N_HINTS = 24
SQUARE_START = 1 << 8
_BSIG = _PREFIX_COARSE + _EG_PREFIX
_BSIGN = _BSIG + (N_CLASSES - _FIRST_BANDELET) * _N_SUM * 3 * _N_GUIDE * N_HINTS
# Format version 16: the significance and the first two magnitude decisions mix their fine and
# coarse contexts with a third, the *activity* context (:func:`_code_mixed`): the class, the octave
# of the neighbours' full magnitudes (``_N_ACTIVITY``: the contexts above clip them at 2) and the
# octave of the guide's magnitude (``_N_GUIDE_OCTAVES``). The Elias-gamma prefix of the larger
# magnitudes is read in a context of the class and that activity, backed by the class's, and so is
# the first bit below its leading one (``_FIRST_BELOW``: the larger half of an octave is the rarer).
_N_ACTIVITY = 12
_N_GUIDE_OCTAVES = 6
_ACTIVITY = _BSIGN + (N_CLASSES - _FIRST_BANDELET) * 54
_PREFIX_ACTIVE = _ACTIVITY + 3 * N_CLASSES * _N_ACTIVITY * _N_GUIDE_OCTAVES
_FIRST_BELOW = _PREFIX_ACTIVE + N_CLASSES * _N_ACTIVITY * _EG_PREFIX
_FIRST_BELOW_COARSE = _FIRST_BELOW + N_CLASSES * _N_ACTIVITY * _EG_PREFIX
# The mixing weights, one set per decision (significance, > 1, > 2) x class x neighbours (0, 1, 2+),
# live in the context table too (a weight of :data:`_W_INIT` is stored as ``_PROB_ONE // 2``, what
# a fresh table holds, so that a coder needs no other state).
_N_INPUTS = 2
_MIX = _FIRST_BELOW_COARSE + N_CLASSES * _EG_PREFIX
_N_COEFF_CONTEXTS = _MIX + 3 * N_CLASSES * 3 * _N_INPUTS
_BACKOFF = 4
_MATURE = _SHIFT.shape[0] - 1  # the count at which a context stops counting


# The kernels run without numba's reference counting (they allocate nothing): with it, each array
# handed to an inlined helper is counted in and out at every decision, by calls that cost five
# times the decision itself (19 ms against 3.3 ms to decode 524,288 flags).
_kernel = njit(cache=True, nogil=True, _nrt=False)


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
        self.state = np.zeros(6, np.int64)
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
        if self.decoding and self.state[_POS] - self.buf.shape[0] > 4:
            raise CorruptStream("coded stream is truncated or corrupt")


@njit(cache=True, nogil=True, inline="always")
def _registers(st):
    """The registers of a coder, as a tuple a kernel threads through its decisions and stores back
    (:func:`_keep`) at its end: a tuple stays in machine registers, the elements of an array are
    reloaded after every store into a context table that might alias them."""
    return st[_LOW], st[_RANGE], st[_CACHE], st[_CACHE_SIZE], st[_POS], st[_SPENT]


@njit(cache=True, nogil=True, inline="always")
def _keep(st, r):
    st[_LOW], st[_RANGE], st[_CACHE], st[_CACHE_SIZE], st[_POS], st[_SPENT] = r


@_kernel
def _shift_low(r, buf):
    low, rng, cache, cache_size, pos, spent = r
    if low < 0xFF000000 or low > 0xFFFFFFFF:
        carry = low >> 32
        temp = cache
        while True:
            buf[pos] = (temp + carry) & 0xFF
            pos += 1
            temp = 0xFF
            cache_size -= 1
            if cache_size == 0:
                break
        cache = (low >> 24) & 0xFF
    return (low & 0x00FFFFFF) << 8, rng, cache, cache_size + 1, pos, spent


@_kernel
def _encoder_flush(st, buf):
    r = _registers(st)
    for _ in range(5):
        r = _shift_low(r, buf)
    _keep(st, r)


@njit(cache=True, nogil=True, inline="always")
def _next_byte(buf, pos):
    """The byte at ``pos``, 0 past the end (the bytes read past it are counted by :meth:`Coder.check`)."""
    return np.int64(buf[pos]) if pos < buf.shape[0] else np.int64(0)


@_kernel
def _decoder_start(st, buf):
    st[_RANGE] = 0xFFFFFFFF
    code = np.int64(0)
    for pos in range(4):
        code = (code << 8) | _next_byte(buf, pos)
    st[_LOW], st[_POS] = code, 4


@njit(cache=True, nogil=True, inline="always")
def _code_at(r, buf, p, bit, decoding):
    """Code one binary decision whose 1 has probability ``p`` (of ``_PROB_ONE``) with the coder
    registers ``r``; returns the bit and the registers."""
    low, rng, cache, cache_size, pos, spent = r
    bound = (rng >> _PROB_BITS) * p
    if decoding:
        bit = 1 if low < bound else 0
    else:
        spent += _COST[(p if bit else _PROB_ONE - p) >> 4]
    if bit:
        rng = bound
    else:
        if not decoding:
            low += bound
        else:
            low -= bound
        rng -= bound
    while rng < _TOP:
        rng <<= 8
        if decoding:
            low = ((low << 8) | _next_byte(buf, pos)) & 0xFFFFFFFF
            pos += 1
        else:
            low, rng, cache, cache_size, pos, spent = _shift_low(
                (low, rng, cache, cache_size, pos, spent), buf
            )
    return bit, (low, rng, cache, cache_size, pos, spent)


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
def _code_bit(r, buf, probs, counts, ctx, bit, decoding):
    """Code one binary decision in context ``ctx``; returns the bit (decoded or given) and the registers."""
    bit, r = _code_at(r, buf, probs[ctx], bit, decoding)
    _adapt(probs, counts, ctx, bit)
    return bit, r


@njit(cache=True, nogil=True, inline="always")
def _code_backed(r, buf, probs, counts, ctx, coarse, bit, decoding):
    """Code one binary decision in context ``ctx`` backed by the ``coarse`` context that it
    refines: while ``ctx`` has been used ``n`` times, its probability is weighted ``n`` against
    ``_BACKOFF`` for the coarse one, so that a rarely used context starts from what its
    neighbours in the table learned instead of from 1/2. Both adapt, until ``ctx`` is mature."""
    n = counts[ctx]
    if n == _MATURE:  # the coarse context's weight would be 3 %: left out, for speed
        return _code_bit(r, buf, probs, counts, ctx, bit, decoding)
    p = (n * probs[ctx] + _BACKOFF * probs[coarse]) // (n + _BACKOFF)
    bit, r = _code_at(r, buf, p, bit, decoding)
    _adapt(probs, counts, ctx, bit)
    _adapt(probs, counts, coarse, bit)
    return bit, r


def _squash_table() -> np.ndarray:
    """``4096 / (1 + exp(-d / 256))`` for ``d`` from -2047 to 2047, in integers (12-bit probabilities)."""
    d = np.arange(-2047, 2048)
    return np.array([int(4096.0 / (1.0 + math.exp(-v / 256.0)) + 0.5) for v in d], np.int64).clip(1, 4095)


def _stretch_table(squash: np.ndarray) -> np.ndarray:
    """The inverse of the squash table: for each 12-bit probability, the least ``d`` it reaches."""
    out = np.empty(4096, np.int64)
    # Integer arithmetic only (the tables must be the same on every machine, the coder's output is).
    k = 0
    for p in range(4096):
        while k < squash.shape[0] - 1 and squash[k] < p:
            k += 1
        out[p] = k - 2047
    return out


_SQUASH = _squash_table()
_STRETCH = _stretch_table(_SQUASH)
#: The mixer's initial weights (16.16 fixed point) of the backed probability and of the activity
#: context's: 0.7 and 0.3, mostly the backed one while the activity contexts are young. A five-input
#: mixer of PAQ's kind (the fine and coarse contexts apart, the fine one's maturity, a bias) made
#: files within 0.7 %, its coefficient decoding 21 % slower; a bias alone, files within 0.2 % for
#: 1.5 ms more at 512 x 512 (``benchmarks/mixed_contexts.py``).
_W_INIT = np.array([45875, 19661], np.int64)


@njit(cache=True, nogil=True, inline="always")
def _code_mixed(r, buf, probs, counts, ctx, coarse, activity, weights, bit, decoding):
    """Code one binary decision from the probability of :func:`_code_backed` (the fine context
    ``ctx`` backed by ``coarse``) mixed with that of the ``activity`` context (format version 16).

    Their stretched probabilities, weighted by the set of weights at ``weights`` and squashed, as
    PAQ's mixers do (Mahoney 2005); the weights then follow the gradient of the code
    length. Integer arithmetic throughout: the encoder and the decoder must compute the same
    probability on every machine. With ``activity < 0``, :func:`_code_backed` alone."""
    if activity < 0:
        return _code_backed(r, buf, probs, counts, ctx, coarse, bit, decoding)
    n = counts[ctx]
    p = probs[ctx] if n == _MATURE else (n * probs[ctx] + _BACKOFF * probs[coarse]) // (n + _BACKOFF)
    s0 = _STRETCH[p >> 4]
    s1 = _STRETCH[probs[activity] >> 4]
    half = _PROB_ONE // 2
    w0 = probs[weights] - half + _W_INIT[0]
    w1 = probs[weights + 1] - half + _W_INIT[1]
    d = (w0 * s0 + w1 * s1) >> 16
    p12 = _SQUASH[min(max(d, -2047), 2047) + 2047]
    bit, r = _code_at(r, buf, min(max(p12 << 4, _PROB_MIN), _PROB_ONE - _PROB_MIN), bit, decoding)
    err = ((bit << 12) - p12) * 5
    # No bound on the weights is needed: each step moves one by at most 5,118, and the products
    # above stay within int64 for far more decisions than any file holds.
    probs[weights] += (s0 * err) >> 13
    probs[weights + 1] += (s1 * err) >> 13
    _adapt(probs, counts, ctx, bit)
    if n != _MATURE:
        _adapt(probs, counts, coarse, bit)
    _adapt(probs, counts, activity, bit)
    return bit, r


_NO_HINTS = np.zeros(0, np.int64)


@njit(cache=True, nogil=True, inline="always")
def _code_raw_bit(r, buf, bit, decoding):
    """Code one equiprobable bit (no context); returns it and the registers."""
    return _code_at(r, buf, _PROB_ONE // 2, bit, decoding)


#: Bit lengths of 0 to 2047, for :func:`_octave`.
_BIT_LENGTHS = np.array([v.bit_length() for v in range(2048)], np.int64)


@njit(cache=True, nogil=True, inline="always")
def _octave(v, most):
    """The bit length of ``v >= 0`` (0 for 0, 1 for 1, 2 for 2-3, ...), at most ``most`` (<= 11):
    a table, where a loop's exit would be mispredicted at every coefficient."""
    return min(_BIT_LENGTHS[min(v, 2047)], most)


# Building blocks of the compiled context models of other modules (bandelets.coding.lossless): a kernel
# takes the registers of a coder's state, codes its decisions, and stores the registers back.
registers, keep_registers = _registers, _keep
code_bit, code_backed, code_raw_bit, octave = _code_bit, _code_backed, _code_raw_bit, _octave
code_mixed = _code_mixed
#: Index, in the registers, of the count of bytes written so far, and of the ideal code length
#: spent so far (in ``1 / COST_SCALE`` bits).
POSITION, SPENT, COST_SCALE = _POS, _SPENT, _COST_SCALE


@_kernel
def _flags(st, buf, probs, counts, bits, ctxs, decoding):
    r = _registers(st)
    for i in range(bits.shape[0]):
        bits[i], r = _code_bit(r, buf, probs, counts, ctxs[i], bits[i], decoding)
    _keep(st, r)


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


@_kernel
def _flag_map(st, buf, probs, counts, bits, ctxs, stride, decoding):
    r = _registers(st)
    for i in range(bits.shape[0]):
        for j in range(bits.shape[1]):
            near = (bits[i, j - 1] if j > 0 else 0) + (bits[i - 1, j] if i > 0 else 0)
            bits[i, j], r = _code_bit(r, buf, probs, counts, ctxs[i, j] + stride * near, bits[i, j], decoding)
    _keep(st, r)


def code_flag_map(coder: Coder, bits: np.ndarray, ctxs: np.ndarray, stride: int) -> np.ndarray:
    """Code a map of binary flags in raster order, each in its context of ``ctxs`` plus ``stride``
    times the count (0 to 2) of its left and upper neighbours that are 1.

    Parameters
    ----------
    coder : Coder
    bits : ndarray of int64, shape (h, w)
        The flags, 0 or 1 (ignored when decoding: pass zeros of the right shape).
    ctxs : ndarray of int64, shape (h, w)
        Context index of each flag before its neighbours are counted.
    stride : int

    Returns
    -------
    ndarray of int64, shape (h, w): the flags (decoded when decoding).
    """
    bits = np.array(bits, np.int64)
    coder.reserve(2 * bits.size)
    _flag_map(
        coder.state,
        coder.buf,
        coder.probs,
        coder.counts,
        bits,
        np.ascontiguousarray(ctxs, np.int64),
        int(stride),
        coder.decoding,
    )
    return bits


@_kernel
def _symbols(st, buf, probs, counts, symbols, bases, n_bits, decoding):
    r = _registers(st)
    for i in range(symbols.shape[0]):
        # Binary tree over n_bits bits, most significant first: node contexts 1 .. 2**n_bits - 1.
        node = 1
        value = symbols[i]
        for b in range(n_bits[i] - 1, -1, -1):
            bit, r = _code_bit(r, buf, probs, counts, bases[i] + node, (value >> b) & 1, decoding)
            node = 2 * node + bit
        symbols[i] = node - (1 << n_bits[i])
    _keep(st, r)


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


@_kernel
def _elias_gamma(r, buf, probs, counts, value, base, decoding, coarse=-1, first=-1, first_coarse=-1):
    """Code ``value >= 1``: adaptive unary prefix ``floor(log2 value)`` (contexts ``base + i``,
    backed by ``coarse + i`` if given), then its low bits equiprobable, but for the first of them in
    context ``first + prefix`` (backed by ``first_coarse + prefix``) if given. Returns ``value``
    (decoded when decoding; -1 if corrupt) and the registers."""
    n_prefix = 0
    while (value >> (n_prefix + 1)) > 0:
        n_prefix += 1
    e = 0
    while True:
        ctx = base + min(e, _EG_PREFIX - 1)
        bit = 1 if e < n_prefix else 0
        if coarse >= 0:
            bit, r = _code_backed(r, buf, probs, counts, ctx, coarse + min(e, _EG_PREFIX - 1), bit, decoding)
        else:
            bit, r = _code_bit(r, buf, probs, counts, ctx, bit, decoding)
        if bit == 0:
            break
        e += 1
        if e > _MAX_PREFIX:
            return -1, r
    out = 1
    for b in range(e - 1, -1, -1):
        if b == e - 1 and first >= 0:
            k = min(e, _EG_PREFIX - 1)
            bit = (value >> b) & 1
            bit, r = _code_backed(r, buf, probs, counts, first + k, first_coarse + k, bit, decoding)
        else:
            bit, r = _code_raw_bit(r, buf, (value >> b) & 1, decoding)
        out = 2 * out + bit
    return out, r


elias_gamma = _elias_gamma  # a building block, as above


@_kernel
def _positive(st, buf, probs, counts, values, bases, decoding):
    r = _registers(st)
    status = 0
    for i in range(values.shape[0]):
        values[i], r = _elias_gamma(r, buf, probs, counts, values[i], bases[i], decoding)
        if values[i] < 0:
            status = -1
            break
    _keep(st, r)
    return status


def code_positive(coder: Coder, values: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """Code integers ``>= 1`` (Elias-gamma with an adaptive prefix in contexts ``base + 0..19``).

    Returns the values (decoded when decoding; pass ones).
    """
    values = np.array(values, np.int64)
    coder.reserve(8 * values.shape[0] + 16)
    bases = np.asarray(bases, np.int64)
    if _positive(coder.state, coder.buf, coder.probs, coder.counts, values, bases, coder.decoding) != 0:
        raise CorruptStream("coded integer stream is corrupt")
    return values


@_kernel
def _decode_coefficients(st, buf, probs, counts, q, known, guide, spent, order, classes, neighbours, hints):
    return _coefficients(
        st, buf, probs, counts, q, known, guide, spent, order, classes, neighbours, hints, True
    )


@_kernel
def _encode_coefficients(st, buf, probs, counts, q, known, guide, spent, order, classes, neighbours, hints):
    return _coefficients(
        st, buf, probs, counts, q, known, guide, spent, order, classes, neighbours, hints, False
    )


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


# Inlined into a decoder and an encoder, each compiled with its constant ``decoding``: 8 % faster.
@njit(cache=True, nogil=True, inline="always")
def _coefficients(
    st, buf, probs, counts, q, known, guide, spent, order, classes, neighbours, hints, decoding
):
    r = _registers(st)
    status = 0
    agree = 0  # in a bandelet square: signs equal to the guide's so far, minus those opposite
    for i in range(order.shape[0]):
        at = order[i]
        before = r[_SPENT]
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
        octave = _octave(activity, _N_ACTIVITY - 1)
        guided = _octave(abs(guide[at]), _N_GUIDE_OCTAVES - 1) if guide.shape[0] > 0 else 0
        active = cls * _N_ACTIVITY + octave
        mixed = _ACTIVITY + active * _N_GUIDE_OCTAVES + guided if cls != _APPROXIMATION else -(1 << 40)
        weights = _MIX + (cls * 3 + min(near, 2)) * _N_INPUTS
        step = N_CLASSES * _N_ACTIVITY * _N_GUIDE_OCTAVES  # the next decision's activity contexts
        step_weights = N_CLASSES * 3 * _N_INPUTS
        if hints.shape[0]:
            fine = _bandelet_significance(cls, ctx, hints[i])
            if hints[i] & SQUARE_START:
                agree = 0
        else:
            fine = _SIG + cls * _N_SUM * 3 * _N_GUIDE + ctx
        significant, r = _code_mixed(
            r, buf, probs, counts, fine, _SIG_COARSE + ctx, mixed, weights, 1 if m > 0 else 0, decoding
        )
        if significant == 0:
            m = 0
        else:
            near5 = min(near, 4) * _N_GUIDE + g
            fine = cls * 5 * _N_GUIDE + near5
            above, r = _code_mixed(
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
                above, r = _code_mixed(
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
                    rest, r = _elias_gamma(
                        r,
                        buf,
                        probs,
                        counts,
                        m - 2,
                        _PREFIX_ACTIVE + active * _EG_PREFIX if mixed >= 0 else _PREFIX,
                        decoding,
                        _PREFIX + cls * _EG_PREFIX if mixed >= 0 else _PREFIX_COARSE,
                        _FIRST_BELOW + active * _EG_PREFIX if mixed >= 0 else -1,
                        _FIRST_BELOW_COARSE + cls * _EG_PREFIX,
                    )
                    if rest < 0 or rest > MAX_MAGNITUDE:
                        status = -1
                        break
                    m = rest + 2
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
            negative, r = _code_backed(
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
            spent[at] = (r[_SPENT] - before) / _COST_SCALE
    _keep(st, r)
    return status


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
    shared context (< 27) and the class's own."""
    if leader != 0:
        sign_ctx += 3 if (leader > 0) == (agree >= 0) else 6
    return sign_ctx, _BSIGN + (cls - _FIRST_BANDELET) * 54 + sign_ctx + (27 if agree != 0 else 0)


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
    status = (_decode_coefficients if coder.decoding else _encode_coefficients)(
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
    )
    if status != 0:
        raise CorruptStream("coded coefficient stream is corrupt")
    coder.check()  # fail at the first run past the end, not after a whole image of zeros
