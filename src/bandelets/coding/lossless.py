"""Lossless coding of integer samples (8 or 16-bit PNG and TIFF sources): the file decodes to the
source's samples bit for bit, every stored channel (format version 12, transform ``lossless``).

How: the samples are visited row by row, the channels of a row in turn, and each is predicted
from its already coded neighbours, either by the median edge detector of LOCO-I (JPEG-LS: the
left or the upper neighbour at an edge, the plane through left, up and up-left elsewhere) or by
a blend of nine predictors each weighted by the inverse square of its recent error around the
sample (:func:`_blend`, after JPEG XL's weighted predictor), whichever codes the file smaller
(:func:`encode_samples`); the z of a normal map is predicted from its x and y where they make
it (:func:`_unit_z`). The prediction is corrected by the mean of the residuals met before in
its context (JPEG-LS's bias cancellation). The residual goes through the project's adaptive
binary range coder (:mod:`bandelets.coding.rangecoder`): a zero flag, a sign, an Elias-gamma magnitude
with an adaptive prefix and the first bit below it in context. A decision's fine context is
the sample's channel, its three signed local gradients (quantized to 7 levels, a context and
its mirror merged, JPEG-LS style), the signed residual of the previous channel at the same
pixel (the channels of a normal map err together at its creases) and the residual energy at
left and up; it is backed by a coarse context (channel, activity in octaves, the previous
channel's residual magnitude) as :mod:`bandelets.coding.rangecoder` backs its own.

Why written here: libraries that code losslessly (libjxl, libavif, libpng through imagecodecs)
write their own containers; a .bdl file has one format, one header and one CRC, read by one
decoder with its limits (:mod:`bandelets.format.header`). The coder is the project's, compiled with
numba with the context modelling as :mod:`bandelets.coding.rangecoder` is.

The encoder may be given a budget of bytes (:func:`encode_samples`): it stops as soon as the
file would exceed it, so that trying the lossless file under a rate target costs little when
it does not fit (:func:`bandelets.codec.encoder.encode_with_stats`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..format.fields import DEFAULT_WAVELET, LOSSLESS, Kind
from ..format.header import HEADER_BYTES, Header, implied_options, pack
from .coefficients import median_of
from .rangecoder import (
    POSITION,
    Coder,
    CorruptStream,
    code_backed,
    code_bit,
    code_flags,
    code_raw_bit,
    keep_registers,
    octave,
    registers,
)

__all__ = ["N_CONTEXTS", "decode_file", "decode_samples", "encode_file", "encode_samples", "samples_of"]

#: Activity buckets: 0, then the octave of the summed gradients (1, 2-3, 4-7, ...).
_N_ACTIVITY = 12
#: Buckets of the previous channel's residual magnitude at the same pixel: 0, 1, 2-3, 4+, and
#: "first channel".
_N_CROSS = 5
_PREFIX = 18  # Elias-gamma prefix contexts: a 16-bit residual has at most 17 bits
# The coarse contexts (channel x activity x cross bucket), each a group of decisions.
_ZERO, _SIGN, _PREFIX_AT, _FIRST_BIT = 0, 1, 2, 2 + _PREFIX
_GROUP = _FIRST_BIT + _PREFIX
_N_COARSE = 4 * _N_ACTIVITY * _N_CROSS
# The fine contexts: channel x three signed gradients quantized to -3..3 x the previous channel's
# residual clipped to -2..2 (or none) x the residual energy at left and up (0, 1-2, 3-6, 7+), one
# per pair of contexts of opposite signs; each refines its coarse one in the zero flag, the sign
# and the first three decisions of the prefix.
_N_FINE = 4 * 7**3 * 6 * 4
_FINE_SLOTS = 5
_FINE = _N_COARSE * _GROUP
# The contexts of the predictors' flags, the stream's first two decisions (0 median, 1 blend;
# the third channel predicted as the z of unit vectors).
_MODE = _FINE + _N_FINE * _FINE_SLOTS
#: Contexts of the coefficient stream of a lossless file, for at most 4 channels.
N_CONTEXTS = _MODE + 2
#: The bias correction's running sums are halved after this many samples of a context.
_BIAS_WINDOW = 64
#: Predictions the blend weighs (:func:`_guesses`).
_N_PREDICTORS = 9


_kernel = njit(cache=True, nogil=True, _nrt=False)


@njit(cache=True, nogil=True, inline="always")
def _octave(v):
    return octave(v, _N_ACTIVITY - 1)


@njit(cache=True, nogil=True, inline="always")
def _level(d, shift):
    """A gradient quantized to -3..3: 0, 1, 2-3, 4+ (after ``shift``), signed."""
    v = abs(d) >> shift
    q = 0 if v == 0 else 1 if v == 1 else 2 if v <= 3 else 3
    return -q if d < 0 else q


@njit(cache=True, nogil=True, inline="always")
def _blend(errors, guesses, c, i, j):
    """The mean of the predictions ``guesses`` (:func:`_guesses`), each weighted by the inverse
    square of the error it made at the four neighbours above and to the left."""
    width = errors.shape[3]
    total = np.int64(0)
    weighted = np.int64(0)
    for k in range(_N_PREDICTORS):
        err = 1
        if j > 0:
            err += errors[k, c, i, j - 1]
        if i > 0:
            err += errors[k, c, i - 1, j]
            if j > 0:
                err += errors[k, c, i - 1, j - 1]
            if j + 1 < width:
                err += errors[k, c, i - 1, j + 1]
        w = max((np.int64(1) << 40) // (err * err), np.int64(1))
        total += w
        weighted += w * guesses[k]
    return (2 * weighted + total) // (2 * total)


@njit(cache=True, nogil=True, inline="always")
def _guesses(guesses, x, c, i, j, med, a, b, nw, ne):
    """Fill ``guesses`` with the predictions the blend weighs (:func:`_blend`): the median, the
    plane through left, up and up-left, left, up, the plane through left, up and up-right, the
    mean of left and up tilted by the slope above, the plane through up, up-right and the one
    above it, and the lines through up and the one above it, through left and the one left of
    it. Each added one paid on the smooth maps (BENCHMARKS, "Lossless files")."""
    guesses[0] = med
    guesses[1] = a + b - nw
    guesses[2] = a
    guesses[3] = b
    guesses[4] = a + ne - b
    guesses[5] = (a + b + 1) // 2 + (ne - nw) // 4
    nne = x[c, i - 2, j + 1] if i > 1 and j + 1 < x.shape[2] else ne
    nn = x[c, i - 2, j] if i > 1 else b
    ww = x[c, i, j - 2] if j > 1 else a
    guesses[6] = b + ne - nne
    guesses[7] = 2 * b - nn
    guesses[8] = 2 * a - ww


@njit(cache=True, nogil=True, inline="always")
def _unit_z(red, green, top):
    """The sample of ``z = sqrt(1 - x^2 - y^2)`` of the unit vector whose ``x, y`` have the
    samples ``red, green`` (as :func:`bandelets.io.files.from_samples` and
    :func:`bandelets.io.files.to_samples` map them; 0 beyond the unit disc)."""
    x = 2.0 * (red / top) - 1.0
    y = 2.0 * (green / top) - 1.0
    zz = 1.0 - (x * x + y * y)
    z = np.sqrt(zz) if zz > 0.0 else 0.0
    return np.int64(np.rint((z + 1.0) / 2.0 * top))


@njit(cache=True, nogil=True, inline="always")
def _neighbours(x, c, i, j, middle):
    """Left, up, up-left, up-right and left-left of sample ``(c, i, j)``, replicated where they fall
    outside the image (``middle`` at the first sample)."""
    width = x.shape[2]
    if j > 0:
        a = x[c, i, j - 1]
    elif i > 0:
        a = x[c, i - 1, j]
    else:
        a = middle
    b = x[c, i - 1, j] if i > 0 else a
    nw = x[c, i - 1, j - 1] if i > 0 and j > 0 else b
    ne = x[c, i - 1, j + 1] if i > 0 and j + 1 < width else b
    ww = x[c, i, j - 2] if j > 1 else a
    return a, b, nw, ne, ww


@njit(cache=True, nogil=True, inline="always")
def _magnitude(r, buf, probs, counts, ctx, coarse, m, decoding):
    """Elias gamma of a magnitude ``m >= 1`` (decoded when ``decoding``): the octave in unary, the
    first three decisions in the sample's fine contexts backed by its coarse ones, then the bits
    below it. Returns the magnitude (-1 for a corrupt stream) and the registers."""
    octave = 0
    while (m >> (octave + 1)) > 0:
        octave += 1
    k = 0
    while True:
        bit = 1 if k < octave else 0
        at = coarse + _PREFIX_AT + min(k, _PREFIX - 1)
        if k < 3:
            more, r = code_backed(r, buf, probs, counts, ctx + 2 + k, at, bit, decoding)
        else:
            more, r = code_bit(r, buf, probs, counts, at, bit, decoding)
        if more == 0:
            break
        k += 1
        if k >= _PREFIX:
            return -1, r
    out = 1
    for low in range(k - 1, -1, -1):
        bit = (m >> low) & 1
        if low == k - 1:
            bit, r = code_bit(r, buf, probs, counts, coarse + _FIRST_BIT + k, bit, decoding)
        else:
            bit, r = code_raw_bit(r, buf, bit, decoding)
        out = 2 * out + bit
    return out, r


@_kernel
def _code(
    st,
    buf,
    probs,
    counts,
    x,
    residuals,
    errors,
    guesses,
    sums,
    uses,
    top,
    shift,
    blend,
    unit,
    rows,
    budget,
    decoding,
):
    """Code (``decoding`` False) or decode the rows ``rows[0]`` to ``rows[1] - 1`` of the samples
    ``x`` (C, H, W), int64 in ``[0, top]``; gradients are quantized after a right ``shift``.

    ``residuals`` (C, H, W), ``sums`` and ``uses`` (one per fine context) are scratch arrays,
    zeros at the first row, kept from one call to the next with ``x`` and the coder. Returns 0,
    1 when the encoder went past ``budget`` bytes (it stops at the end of the row), -1 for a
    corrupt stream.
    """
    n_channels, height, width = x.shape
    r = registers(st)
    status = 0
    middle = (top + 1) // 2
    for i in range(rows[0], rows[1]):
        for c in range(n_channels):
            for j in range(width):
                a, b, nw, ne, ww = _neighbours(x, c, i, j, middle)
                med = median_of(a, b, nw)
                predicted = med
                if unit and c == 2:
                    predicted = _unit_z(x[0, i, j], x[1, i, j], top)
                elif blend:
                    _guesses(guesses, x, c, i, j, med, a, b, nw, ne)
                    predicted = _blend(errors, guesses, c, i, j)

                g1, g2, g3 = ne - b, b - nw, nw - a
                q1, q2, q3 = _level(g1, shift), _level(g2, shift), _level(g3, shift)
                e = residuals[c - 1, i, j] if c > 0 else 0
                q4 = min(max(e, -2), 2)
                # A context and its mirror (every sign turned) share their statistics, the
                # residual's sign turned.
                flip = 1
                if q1 < 0 or (q1 == 0 and (q2 < 0 or (q2 == 0 and (q3 < 0 or (q3 == 0 and q4 < 0))))):
                    flip = -1
                    q1, q2, q3, q4 = -q1, -q2, -q3, -q4
                fine = ((c * 7 + q1 + 3) * 7 + q2 + 3) * 7 + q3 + 3
                fine = fine * 6 + (q4 + 2 if c > 0 else 5)
                energy = (abs(residuals[c, i, j - 1]) if j > 0 else 0) + (
                    abs(residuals[c, i - 1, j]) if i > 0 else 0
                )
                energy >>= shift
                fine = fine * 4 + (0 if energy == 0 else 1 if energy <= 2 else 2 if energy <= 6 else 3)
                ew = abs(residuals[c, i, j - 1]) if j > 0 else 0
                en = abs(residuals[c, i - 1, j]) if i > 0 else 0
                ene = abs(residuals[c, i - 1, j + 1]) if i > 0 and j + 1 < width else en
                activity = _octave(abs(g1) + abs(g2) + abs(g3) + abs(a - ww) + 2 * (ew + en) + ene)
                cross = min(_octave(abs(e)), _N_CROSS - 2) if c > 0 else _N_CROSS - 1
                coarse = ((c * _N_ACTIVITY + activity) * _N_CROSS + cross) * _GROUP
                # Bias cancellation: the mean residual of the context, rounded.
                n = uses[fine]
                if n > 0:
                    s = sums[fine]
                    bias = (2 * s + n) // (2 * n) if s >= 0 else -((-2 * s + n) // (2 * n))
                    predicted += flip * bias
                predicted = min(max(predicted, 0), top)
                ctx = _FINE + fine * _FINE_SLOTS
                value = 0 if decoding else flip * (x[c, i, j] - predicted)
                m = abs(value)
                nonzero, r = code_backed(
                    r, buf, probs, counts, ctx, coarse + _ZERO, 1 if m > 0 else 0, decoding
                )
                if nonzero:
                    negative, r = code_backed(
                        r, buf, probs, counts, ctx + 1, coarse + _SIGN, 1 if value < 0 else 0, decoding
                    )
                    out, r = _magnitude(r, buf, probs, counts, ctx, coarse, m, decoding)
                    if out < 0:
                        status = -1
                        break
                    value = -out if negative else out
                if decoding:
                    sample = predicted + flip * value
                    if sample < 0 or sample > top:
                        status = -1
                        break
                    x[c, i, j] = sample
                residuals[c, i, j] = flip * value
                if blend:
                    sample = x[c, i, j]
                    if unit and c == 2:  # the blend's guesses were not made
                        _guesses(guesses, x, c, i, j, med, a, b, nw, ne)
                    for k in range(_N_PREDICTORS):
                        errors[k, c, i, j] = abs(sample - guesses[k])
                if n == _BIAS_WINDOW:
                    sums[fine] >>= 1
                    n >>= 1
                sums[fine] += value
                uses[fine] = n + 1
            if status != 0:
                break
        if status != 0:
            break
        if not decoding and r[POSITION] > budget:
            status = 1
            break
    keep_registers(st, r)
    return status


#: Most bytes one sample can take: 2 depth + 3 decisions (zero, sign, prefix, bits), each of at
#: most 11 bits (the probabilities stay within 32 / 65536 of 0 and 1).
def _worst_bytes(depth: int) -> int:
    return (2 * depth + 3) * 11 // 8 + 1


def _run(
    coder: Coder,
    x: np.ndarray,
    depth: int,
    blend: bool,
    unit: bool,
    budget: int | None,
    rows: tuple[int, int] | None = None,
) -> int:
    """Code or decode the samples ``x`` (C, H, W) in chunks of rows (of ``rows``, start and stop:
    all by default), the encoder's buffer grown before each to hold its worst case; the status of
    :func:`_code`."""
    errors = np.zeros((_N_PREDICTORS, *x.shape) if blend else (_N_PREDICTORS, 0, 0, 0), np.int64)
    scratch = (
        np.zeros(x.shape, np.int64),
        errors,
        np.zeros(_N_PREDICTORS, np.int64),
        np.zeros(_N_FINE, np.int64),
        np.zeros(_N_FINE, np.int64),
    )
    row_bytes = x.shape[0] * x.shape[2] * _worst_bytes(depth)
    chunk = max(1, 2**20 // row_bytes)
    limit = np.iinfo(np.int64).max if budget is None else min(budget, np.iinfo(np.int64).max)  # bpp=1e300
    first, last = (0, x.shape[1]) if rows is None else rows
    for start in range(first, last, chunk):
        stop = min(start + chunk, last)
        coder.reserve(row_bytes * (stop - start))
        rows = np.array([start, stop], np.int64)
        args = (coder.state, coder.buf, coder.probs, coder.counts, x, *scratch)
        status = _code(*args, 2**depth - 1, (depth - 8) // 2, blend, unit, rows, limit, coder.decoding)
        if status != 0:
            return status
    return 0


#: Rows a size estimate codes: bands of this many rows, one in every ``_SAMPLED_EVERY``.
_SAMPLED_ROWS, _SAMPLED_EVERY = 8, 8


def estimated_bytes(samples: np.ndarray, depth: int, normals: bool = False) -> float:
    """The size of :func:`encode_samples`'s stream predicted from one band of rows in eight, coded
    with the median predictor (the rows between them are read as neighbours, not coded): within
    about 10 % on the shared maps (``benchmarks/lossless.py --estimate``), an eighth of the time
    of the median pass. Whether a rate target's lossless try can fit at all is decided from it.
    """
    x = np.ascontiguousarray(np.moveaxis(samples, -1, 0), np.int64)
    height = x.shape[1]
    if height <= 2 * _SAMPLED_ROWS * _SAMPLED_EVERY:
        coder = Coder(N_CONTEXTS)
        _run(coder, x, depth, False, normals and samples.shape[2] == 3, None)
        return float(len(coder.finish()))
    bands = [
        (start, min(start + _SAMPLED_ROWS, height))
        for start in range(0, height, _SAMPLED_ROWS * _SAMPLED_EVERY)
    ]
    sampled = np.concatenate([samples[start:stop] for start, stop in bands])
    unit = normals and samples.shape[2] == 3 and _unit_pays(sampled, depth)
    coder = Coder(N_CONTEXTS)
    for band in bands:
        _run(coder, x, depth, False, unit, None, band)
    return len(coder.finish()) * height / len(sampled)


def _unit_pays(samples: np.ndarray, depth: int) -> bool:
    """Whether the third channel of ``samples`` (H, W, 3) is closer to the ``z`` of unit vectors
    made from the first two (:func:`_unit_z`) than to its left neighbour, summed over the image:
    a normal map whose blue is ``z``, not something else (ambient occlusion)."""
    from ..format.samples import from_samples, to_samples
    from ..transform.normals import with_z

    blue = samples[..., 2].astype(np.int64)
    z = to_samples(with_z(from_samples(samples[..., :2], "normal-map", depth)), "normal-map", depth)[..., 2]
    return int(np.abs(blue - z).sum()) < int(np.abs(np.diff(blue, axis=1)).sum())


def encode_samples(
    samples: np.ndarray, depth: int, budget: int | None = None, normals: bool = False
) -> bytes | None:
    """The coded stream of integer samples, or None when it would exceed ``budget`` bytes.

    Both predictors are tried (the median edge detector, then the blend, :func:`_blend`) and the
    smaller stream kept: its first decision says which. The median wins on the lava map (a
    palette of 175 vectors: 1.27 against 1.69 bpp with a blend of four), the blend on smooth
    16-bit maps (the bumps map at 256: 20.4 against 22.4 bpp, blend of four) and the acacia door
    (18.2 against 18.5). With
    ``normals`` (the channels of a normal map, x, y, z), the third channel is predicted as the
    ``z`` of the unit vector of the first two (:func:`_unit_z`) where that is the closer guess
    (:func:`_unit_pays`; the second decision says so): on the acacia door whose z is rebuilt,
    the z channel costs nothing but its rounding.

    Parameters
    ----------
    samples : ndarray of unsigned integers, shape (H, W, C), C from 1 to 4
    depth : {8, 16}
        Bits of every sample.
    budget : int, optional
        Stop and return None as soon as the stream passes this many bytes.
    normals : bool
        The samples are the x, y, z of a normal map.
    """
    x = np.ascontiguousarray(np.moveaxis(samples, -1, 0), np.int64)
    unit = normals and samples.shape[2] == 3 and _unit_pays(samples, depth)
    best = None
    for blend in (False, True):
        coder = Coder(N_CONTEXTS)
        code_flags(coder, np.array([int(blend), int(unit)]), np.array([_MODE, _MODE + 1]))
        if _run(coder, x, depth, blend, unit, budget) == 0:
            data = coder.finish()
            if (budget is None or len(data) <= budget) and (best is None or len(data) < len(best)):
                best = data
        if best is not None:
            budget = len(best) - 1  # the second need only beat the first
    return best


def decode_samples(data: bytes, height: int, width: int, channels: int, depth: int) -> np.ndarray:
    """The samples a stream of :func:`encode_samples` holds, ``uint8`` or ``uint16`` (H, W, C);
    :class:`bandelets.coding.rangecoder.CorruptStream` when it holds none."""
    coder = Coder(N_CONTEXTS, data)
    x = np.zeros((channels, height, width), np.int64)
    blend, unit = (bool(f) for f in code_flags(coder, np.zeros(2, np.int64), np.array([_MODE, _MODE + 1])))
    if _run(coder, x, depth, blend, unit and channels == 3, None) != 0:
        raise CorruptStream("coded sample stream is corrupt")
    coder.check()
    return np.ascontiguousarray(np.moveaxis(x, 0, -1), np.uint8 if depth == 8 else np.uint16)


def samples_of(array, kind: str, depth: int) -> tuple[np.ndarray, int] | None:
    """The unsigned integer samples (H, W, C) an array stands for and their depth, or None.

    ``array``: ``uint8`` / ``uint16`` samples of a normal map, or values read from samples of
    ``depth`` bits (:func:`bandelets.io.files.from_samples`: what the command line reads from a PNG
    or TIFF file) of any kind but a geometry image. Floats off that grid (or ``depth`` 0) are not
    samples. ``ValueError`` for an array that no encoding takes (its shape, a normal map's
    integer type).
    """
    from ..format.samples import from_samples, integer_samples, to_samples

    array = np.asarray(array)
    given = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16}.get(array.dtype)
    if kind == Kind.NORMAL_MAP and given is not None and depth in (0, given):
        values, depth = array, given  # the samples themselves: no float copy of them
    else:
        values, depth = integer_samples(array, kind, depth)
        if depth not in (8, 16) or values.dtype.kind != "f":
            return None
    values = values[..., None] if values.ndim == 2 else values
    channels = values.shape[2] if values.ndim == 3 else 0
    if (
        kind == Kind.GEOMETRY_IMAGE
        or not (1 <= channels <= 4 and (kind == Kind.IMAGE or channels in (2, 3)))
        or values.shape[0] * values.shape[1] < 2
    ):
        return None
    if values.dtype.kind == "u":
        return np.ascontiguousarray(values), depth
    samples = to_samples(values, kind, depth)
    return (samples, depth) if np.array_equal(from_samples(samples, kind, depth), values) else None


def encode_file(samples: np.ndarray, kind: str, depth: int, budget: int | None = None) -> bytes | None:
    """The lossless .bdl file of ``samples`` (H, W, C) of ``depth`` bits, or None when it would
    be larger than ``budget`` bytes."""
    height, width, channels = samples.shape
    header = Header(
        height=height,
        width=width,
        channels=channels,
        kind=kind,
        transform=LOSSLESS,
        wavelet=DEFAULT_WAVELET,
        levels=1,
        threshold=1.0,
        depth=depth,
        layout="xy" if kind == Kind.NORMAL_MAP and channels == 2 else "xyz",
        **implied_options(kind, channels),
    )
    room = None if budget is None else budget - HEADER_BYTES
    if room is not None and room < 0:
        return None
    stream = encode_samples(samples, depth, room, normals=kind == Kind.NORMAL_MAP)
    return None if stream is None else pack(header, (b"", b"", stream))


def decode_file(header: Header, stream: bytes) -> np.ndarray:
    """What :func:`bandelets.decode` returns for a lossless file: the values of its samples
    (:func:`bandelets.io.files.from_samples`), (H, W) or (H, W, C)."""
    from ..format.samples import from_samples

    samples = decode_samples(stream, header.height, header.width, header.channels, header.depth)
    values = from_samples(samples, header.kind, header.depth)
    return values[..., 0] if header.channels == 1 else values
