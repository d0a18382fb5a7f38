"""An adaptive binary range coder, and the building blocks of the context models it is driven by.

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
    "COST_SCALE",
    "EG_PREFIX",
    "N_INPUTS",
    "POSITION",
    "SPENT",
    "Coder",
    "CorruptStream",
    "code_backed",
    "code_bit",
    "code_flag_map",
    "code_flags",
    "code_mixed",
    "code_positive",
    "code_raw_bit",
    "code_symbols",
    "elias_gamma",
    "keep_registers",
    "kernel",
    "octave",
    "registers",
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
_LOW, _RANGE, _CACHE, _CACHE_SIZE, POSITION, SPENT = range(6)
COST_SCALE = 65536.0
# -log2 of a probability, tabulated on 12 bits: the ledger of what each decision costs.
_COST = np.rint(-np.log2((np.arange(4096) + 0.5) / 4096) * COST_SCALE).astype(np.int64)

EG_PREFIX = 20
MAX_PREFIX = 31
# The mixing weights, one set per decision (significance, > 1, > 2) x class x neighbours (0, 1, 2+),
# live in the context table too (a weight of :data:`_W_INIT` is stored as ``_PROB_ONE // 2``, what
# a fresh table holds, so that a coder needs no other state).
N_INPUTS = 2
BACKOFF = 4
MATURE = _SHIFT.shape[0] - 1  # the count at which a context stops counting


# The kernels run without numba's reference counting (they allocate nothing): with it, each array
# handed to an inlined helper is counted in and out at every decision, by calls that cost five
# times the decision itself (19 ms against 3.3 ms to decode 524,288 flags).
kernel = njit(cache=True, nogil=True, _nrt=False)


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
        #: The segments to decode after this one; those the encoder has cut (format version 19, :meth:`cut`).
        self.pending: list[bytes] = []
        self.segments: list[bytes] = []
        if self.decoding:
            self.buf = np.frombuffer(bytes(data), np.uint8).copy()
            _decoder_start(self.state, self.buf)
        else:
            self.buf = np.zeros(capacity, np.uint8)
            self.state[_RANGE] = 0xFFFFFFFF
            self.state[_CACHE_SIZE] = 1

    def reserve(self, n_bytes: int) -> None:
        """Make sure the encoder can write ``n_bytes`` more bytes."""
        need = int(self.state[POSITION]) + n_bytes + 16
        if not self.decoding and need > self.buf.shape[0]:
            grown = np.zeros(max(need, 2 * self.buf.shape[0]), np.uint8)
            grown[: self.buf.shape[0]] = self.buf
            self.buf = grown

    def finish(self) -> bytes:
        """Flush the encoder and return the stream."""
        self.reserve(8)
        _encoder_flush(self.state, self.buf)
        # The first byte of this coder's output is always the initial zero cache: not stored.
        return self.buf[1 : self.state[POSITION]].tobytes()

    def check(self) -> None:
        """Raise :class:`CorruptStream` if the decoder ran past the end of its stream."""
        if self.decoding and self.state[POSITION] - self.buf.shape[0] > 4:
            raise CorruptStream("coded stream is truncated or corrupt")

    def cut(self, following: bytes | None = None) -> bytes:
        """End a segment of the stream (format version 19: one per wavelet level, so that a prefix of
        a file decodes): the arithmetic state restarts, the adaptive contexts go on.

        Encoder: flushes the fewest bytes that decode to what was coded (:func:`_short_flush`;
        trailing zeros are not stored, the decoder reads zeros past the end of a segment) and
        returns the segment. Decoder: checks the segment just read and starts on ``following``.
        """
        if self.decoding:
            self.check()
            self.buf = np.frombuffer(bytes(following or b""), np.uint8).copy()
            _decoder_start(self.state, self.buf)
            return b""
        self.reserve(8)
        _short_flush(self.state, self.buf)
        data = self.buf[1 : self.state[POSITION]].tobytes()
        # At most 4 zeros dropped: the decoder reads 4 bytes ahead (check() allows that much).
        stripped = data.rstrip(b"\0")
        data = data[: max(len(stripped), len(data) - 4)]
        spent = self.state[SPENT]
        self.state[:] = 0
        self.state[_RANGE], self.state[_CACHE_SIZE], self.state[SPENT] = 0xFFFFFFFF, 1, spent
        return data


@njit(cache=True, nogil=True, inline="always")
def registers(st):
    """The registers of a coder, as a tuple a kernel threads through its decisions and stores back
    (:func:`keep_registers`) at its end: a tuple stays in machine registers, the elements of an array are
    reloaded after every store into a context table that might alias them."""
    return st[_LOW], st[_RANGE], st[_CACHE], st[_CACHE_SIZE], st[POSITION], st[SPENT]


@njit(cache=True, nogil=True, inline="always")
def keep_registers(st, r):
    st[_LOW], st[_RANGE], st[_CACHE], st[_CACHE_SIZE], st[POSITION], st[SPENT] = r


@kernel
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


@kernel
def _encoder_flush(st, buf):
    r = registers(st)
    for _ in range(5):
        r = _shift_low(r, buf)
    keep_registers(st, r)


@kernel
def _short_flush(st, buf):
    """Flush with the value of the final interval ``[low, low + range)`` that ends in the most zero
    bits, so that its trailing zero bytes need not be stored: 1 or 2 bytes where a full flush
    writes 4."""
    r = registers(st)
    low, rng = r[0], r[1]
    for bits in range(32, -1, -1):
        step = np.int64(1) << bits
        value = (low + step - 1) >> bits << bits
        if value < low + rng:
            break
    r = (value, rng, r[2], r[3], r[4], r[5])
    for _ in range(5):
        r = _shift_low(r, buf)
    keep_registers(st, r)


@njit(cache=True, nogil=True, inline="always")
def _next_byte(buf, pos):
    """The byte at ``pos``, 0 past the end (the bytes read past it are counted by :meth:`Coder.check`)."""
    return np.int64(buf[pos]) if pos < buf.shape[0] else np.int64(0)


@kernel
def _decoder_start(st, buf):
    st[_RANGE] = 0xFFFFFFFF
    code = np.int64(0)
    for pos in range(4):
        code = (code << 8) | _next_byte(buf, pos)
    st[_LOW], st[POSITION] = code, 4


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
def code_bit(r, buf, probs, counts, ctx, bit, decoding):
    """Code one binary decision in context ``ctx``; returns the bit (decoded or given) and the registers."""
    bit, r = _code_at(r, buf, probs[ctx], bit, decoding)
    _adapt(probs, counts, ctx, bit)
    return bit, r


@njit(cache=True, nogil=True, inline="always")
def code_backed(r, buf, probs, counts, ctx, coarse, bit, decoding):
    """Code one binary decision in context ``ctx`` backed by the ``coarse`` context that it
    refines: while ``ctx`` has been used ``n`` times, its probability is weighted ``n`` against
    ``BACKOFF`` for the coarse one, so that a rarely used context starts from what its
    neighbours in the table learned instead of from 1/2. Both adapt, until ``ctx`` is mature."""
    n = counts[ctx]
    if n == MATURE:  # the coarse context's weight would be 3 %: left out, for speed
        return code_bit(r, buf, probs, counts, ctx, bit, decoding)
    p = (n * probs[ctx] + BACKOFF * probs[coarse]) // (n + BACKOFF)
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
def code_mixed(r, buf, probs, counts, ctx, coarse, activity, weights, bit, decoding):
    """Code one binary decision from the probability of :func:`code_backed` (the fine context
    ``ctx`` backed by ``coarse``) mixed with that of the ``activity`` context (format version 16).

    Their stretched probabilities, weighted by the set of weights at ``weights`` and squashed, as
    PAQ's mixers do (Mahoney 2005); the weights then follow the gradient of the code
    length. Integer arithmetic throughout: the encoder and the decoder must compute the same
    probability on every machine. With ``activity < 0``, :func:`code_backed` alone."""
    if activity < 0:
        return code_backed(r, buf, probs, counts, ctx, coarse, bit, decoding)
    n = counts[ctx]
    p = probs[ctx] if n == MATURE else (n * probs[ctx] + BACKOFF * probs[coarse]) // (n + BACKOFF)
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
    if n != MATURE:
        _adapt(probs, counts, coarse, bit)
    _adapt(probs, counts, activity, bit)
    return bit, r


@njit(cache=True, nogil=True, inline="always")
def code_raw_bit(r, buf, bit, decoding):
    """Code one equiprobable bit (no context); returns it and the registers."""
    return _code_at(r, buf, _PROB_ONE // 2, bit, decoding)


#: Bit lengths of 0 to 2047, for :func:`octave`.
_BIT_LENGTHS = np.array([v.bit_length() for v in range(2048)], np.int64)


@njit(cache=True, nogil=True, inline="always")
def octave(v, most):
    """The bit length of ``v >= 0`` (0 for 0, 1 for 1, 2 for 2-3, ...), at most ``most`` (<= 11):
    a table, where a loop's exit would be mispredicted at every coefficient."""
    return min(_BIT_LENGTHS[min(v, 2047)], most)


@kernel
def _flags(st, buf, probs, counts, bits, ctxs, decoding):
    r = registers(st)
    for i in range(bits.shape[0]):
        bits[i], r = code_bit(r, buf, probs, counts, ctxs[i], bits[i], decoding)
    keep_registers(st, r)


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


@kernel
def _flag_map(st, buf, probs, counts, bits, ctxs, stride, decoding):
    r = registers(st)
    for i in range(bits.shape[0]):
        for j in range(bits.shape[1]):
            near = (bits[i, j - 1] if j > 0 else 0) + (bits[i - 1, j] if i > 0 else 0)
            bits[i, j], r = code_bit(r, buf, probs, counts, ctxs[i, j] + stride * near, bits[i, j], decoding)
    keep_registers(st, r)


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


@kernel
def _symbols(st, buf, probs, counts, symbols, bases, n_bits, decoding):
    r = registers(st)
    for i in range(symbols.shape[0]):
        # Binary tree over n_bits bits, most significant first: node contexts 1 .. 2**n_bits - 1.
        node = 1
        value = symbols[i]
        for b in range(n_bits[i] - 1, -1, -1):
            bit, r = code_bit(r, buf, probs, counts, bases[i] + node, (value >> b) & 1, decoding)
            node = 2 * node + bit
        symbols[i] = node - (1 << n_bits[i])
    keep_registers(st, r)


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


@kernel
def elias_gamma(r, buf, probs, counts, value, base, decoding, coarse=-1, first=-1, first_coarse=-1):
    """Code ``value >= 1``: adaptive unary prefix ``floor(log2 value)`` (contexts ``base + i``,
    backed by ``coarse + i`` if given), then its low bits equiprobable, but for the first of them in
    context ``first + prefix`` (backed by ``first_coarse + prefix``) if given. Returns ``value``
    (decoded when decoding; -1 if corrupt) and the registers."""
    n_prefix = 0
    while (value >> (n_prefix + 1)) > 0:
        n_prefix += 1
    e = 0
    while True:
        ctx = base + min(e, EG_PREFIX - 1)
        bit = 1 if e < n_prefix else 0
        if coarse >= 0:
            bit, r = code_backed(r, buf, probs, counts, ctx, coarse + min(e, EG_PREFIX - 1), bit, decoding)
        else:
            bit, r = code_bit(r, buf, probs, counts, ctx, bit, decoding)
        if bit == 0:
            break
        e += 1
        if e > MAX_PREFIX:
            return -1, r
    out = 1
    for b in range(e - 1, -1, -1):
        if b == e - 1 and first >= 0:
            k = min(e, EG_PREFIX - 1)
            bit = (value >> b) & 1
            bit, r = code_backed(r, buf, probs, counts, first + k, first_coarse + k, bit, decoding)
        else:
            bit, r = code_raw_bit(r, buf, (value >> b) & 1, decoding)
        out = 2 * out + bit
    return out, r


@kernel
def _positive(st, buf, probs, counts, values, bases, decoding):
    r = registers(st)
    status = 0
    for i in range(values.shape[0]):
        # Every argument given, as int64 (numba compiles a literal or an omitted argument as a type of its
        # own): the coders share one specialization of elias_gamma, not three (4 s of compilation each).
        none = np.int64(-1)
        values[i], r = elias_gamma(r, buf, probs, counts, values[i], bases[i], decoding, none, none, none)
        if values[i] < 0:
            status = -1
            break
    keep_registers(st, r)
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
