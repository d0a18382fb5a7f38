"""Compiled lifting passes of the 2D wavelet transforms of :mod:`bandelets.transform.wavelets`.

A pass lifts every line of a block along one axis, reading the interleaved samples of a source
block and writing the split layout (low half, then high half) of a destination block, or back:
one read and one write of the block per pass and, for CDF 9/7, four in-place sweeps for its
lifting steps, where numpy needed a split, a concatenation and a shifted copy per step. A
column pass runs its inner loops along the rows of memory. The arithmetic is that of the numpy
lifting it replaced, term by term and in the same order (``tests/reference.py`` keeps that
one), so the coefficients are the same to the last bit.

The passes run in one thread and let go of the GIL: the restoration transforms the channels in
threads of its own. Numba's ``parallel=True`` over the lines was tried and lost on the shared
2-core machine: 0.42 s instead of 0.013 s for a 512 x 512 analysis (each of the 72 parallel
loops of a 6-level transform waits for threads the other processes hold).

Written here rather than taken from PyWavelets: its CDF 9/7 is not critically sampled with a
symmetric extension, the spherical extension of octahedral geometry images exists nowhere else
(see :mod:`bandelets.transform.wavelets`), and its Haar is 8 times slower: an analysis and a synthesis
of a 512 x 512 channel over 6 levels take 2.3 ms of CPU here against 18.5 ms through
:func:`pywt.wavedec2` (CDF 9/7: 6.0 ms against 23.3 ms for the numpy lifting).

A pass takes its blocks as ``(lines, samples)`` arrays: a column pass is handed the transposes
(views) of its blocks. The extension of a line past its ends comes, at each step, from the
current samples of every line (:func:`_after`, :func:`_before`): the spherical extension of a
line reads the line mirrored along the edge (linear interpolation between lines ``first`` and
``second`` with ``weight``, :func:`bandelets.transform.wavelets.spherical_folds`), which must be that of
the same step for every step to stay exactly invertible.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..runtime.signatures import kernel

__all__ = ["cdf97_pass", "directional_pass", "haar_pass", "scale_subbands"]

# Lifting factorisation of the CDF 9/7 filter pair (Daubechies and Sweldens 1998).
ALPHA = -1.586134342059924
BETA = -0.052980118572961
GAMMA = 0.882911075530934
DELTA = 0.443506852043971
ZETA = 1.230174104914001

# PyWavelets' Haar filter taps.
_SQRT_HALF = 0.7071067811865476


def _layouts(signature: str) -> tuple[str, str]:
    """``signature``, its blocks written ``X``, for row-major blocks and for blocks of any layout.

    Numba compiles a kernel anew for every layout it is handed: the passes take row-major blocks,
    their transposes and corners of larger arrays, three compilations of each pass on a first run.
    The row-major one is kept (the finest level's row passes and the direction search's trials run
    their inner loops vectorised: a 512 x 512 analysis with every pass compiled for any layout took
    20 % longer); transposes and corners share the other (:mod:`bandelets.runtime.signatures`).
    """
    return signature.replace("X", "f8[:, ::1]"), signature.replace("X", "f8[:, :]")


@njit(cache=True, nogil=True)
def _folded(v, first, second, weight, i):
    return (1.0 - weight[i]) * v[first[i]] + weight[i] * v[second[i]]


@njit(cache=True, nogil=True)
def _after(x, n, spherical, first, second, weight, h):
    """The sample of ``s`` past the end of every line of ``x`` (split layout, ``n`` per half)."""
    lines = x.shape[0]
    out = np.empty(lines)
    last = np.empty(lines)
    previous = np.empty(lines)
    for i in range(lines):
        last[i] = x[i, n - 1]
        previous[i] = x[i, max(n - 2, 0)]
    if not spherical:
        return last
    for i in range(lines):
        if h == 1 and n > 1:
            # The finest level continues the fold's far side from its two nearest samples.
            out[i] = 1.5 * _folded(last, first, second, weight, i) - 0.5 * _folded(
                previous, first, second, weight, i
            )
        else:
            out[i] = ((2 * h - 1) * last[i] + 2 * h * _folded(last, first, second, weight, i)) / (4 * h - 1)
    return out


@njit(cache=True, nogil=True)
def _before(x, n, spherical, first, second, weight, h):
    """The sample of ``d`` before the start of every line of ``x`` (split layout)."""
    lines = x.shape[0]
    out = np.empty(lines)
    head = np.empty(lines)
    following = np.empty(lines)
    for i in range(lines):
        head[i] = x[i, n]
        following[i] = x[i, n + min(1, n - 1)]
    if not spherical:
        return head
    for i in range(lines):
        if h == 1 and n > 1:
            out[i] = 1.5 * _folded(head, first, second, weight, i) - 0.5 * _folded(
                following, first, second, weight, i
            )
        else:
            out[i] = (head[i] + 2 * h * _folded(head, first, second, weight, i)) / (2 * h + 1)
    return out


@njit(cache=True, nogil=True)
def _step(x, c, odd, edge, by_lines):
    """One lifting step on every line of ``x`` (split layout ``s, d``): ``d[j] += c (s[j] + s[j + 1])``
    (even step) or ``s[j] += c (d[j] + d[j - 1])`` (odd step), ``edge[i]`` standing for the
    neighbour of line ``i`` past its end."""
    lines, n = x.shape[0], x.shape[1] // 2
    # Offsets into the line: the half updated, the half read and the side of the neighbour;
    # the updates whose neighbour lies inside the line, and the one that reads the edge.
    target, source, shift = (0, n, -1) if odd else (n, 0, 1)
    low, high = (1, n) if odd else (0, n - 1)
    last = 0 if odd else n - 1
    if by_lines:
        for i in range(lines):
            for j in range(low, high):
                x[i, target + j] = x[i, target + j] + c * (x[i, source + j] + x[i, source + j + shift])
    else:
        for j in range(low, high):
            for i in range(lines):
                x[i, target + j] = x[i, target + j] + c * (x[i, source + j] + x[i, source + j + shift])
    for i in range(lines):
        x[i, target + last] = x[i, target + last] + c * (x[i, source + last] + edge[i])


@kernel(*_layouts("void(X, b1, b1, b1, i8[:], i8[:], f8[:], i8)"))
def _lift(x, forward, by_lines, spherical, first, second, weight, h):
    """The four lifting steps of CDF 9/7 (or their inverse), in place on ``x`` (split layout)."""
    n = x.shape[1] // 2
    factors = (ALPHA, BETA, GAMMA, DELTA)
    for step in range(4):
        k = step if forward else 3 - step
        odd = k % 2 == 1
        if odd:
            edge = _before(x, n, spherical, first, second, weight, h)
        else:
            edge = _after(x, n, spherical, first, second, weight, h)
        # Minus the factor: x - c y and x + (-c) y are the same number.
        _step(x, factors[k] if forward else -factors[k], odd, edge, by_lines)


@njit(cache=True, nogil=True, inline="always")
def _line_at(lines, pos):
    """Lines ``i, i + 1`` and weight ``f`` of the linear interpolation at line ``pos`` of
    ``lines``, mirrored at the ends."""
    if pos < 0.0:
        pos = -pos
    if pos > lines - 1:
        pos = max(2.0 * (lines - 1) - pos, 0.0)
    i = int(pos)
    if i >= lines - 1:
        return lines - 1, lines - 1, 0.0
    return i, i + 1, pos - i


@kernel(*_layouts("void(X, b1, b1, i8[:, :], f8[:], f8[:, :, :], i8, i8)"))
def _lift_along(x, forward, by_lines, codes, slopes, weights, block, steps):
    """The first ``steps`` lifting steps of the filters of :func:`directional_pass` (or of their
    inverse), in place on ``x`` (split layout, ``n`` per half), each block of ``block`` lines and
    ``block // 2`` samples reading the other half along its slope ``slopes[codes[a, b]]`` (lines
    per sample) with its weights ``weights[codes[a, b], step]``.

    A step adds ``p u + q v`` to each sample, ``(p, q)`` the step's weights, ``u`` and ``v`` its two
    neighbours on the other half (predict: ``s[k]``, ``s[k + 1]`` to ``d[k]``; update: ``d[k - 1]``,
    ``d[k]`` to ``s[k]``; mirrored at the line's ends) read at lines ``r - slope`` and
    ``r + slope``, linearly interpolated between lines (mirrored at the first and last). The
    blocks of a run of one code along a line (along memory, in a column pass) are lifted together.
    """
    lines, n = x.shape[0], x.shape[1] // 2
    width = block // 2
    for step in range(steps):
        k = step if forward else 3 - step
        sign = 1.0 if forward else -1.0
        predict = k % 2 == 0
        target, source, shift = (n, 0, 1) if predict else (0, n, -1)
        if by_lines:  # runs along the lines
            for a in range(codes.shape[0]):
                b = 0
                while b < codes.shape[1]:
                    end = b + 1
                    while end < codes.shape[1] and codes[a, end] == codes[a, b]:
                        end += 1
                    top, bottom = a * block, min((a + 1) * block, lines)
                    left, right = b * width, min(end * width, n)
                    code = codes[a, b]
                    _lift_run(
                        x, top, bottom, left, right, slopes[code], sign * weights[code, k, 0],
                        sign * weights[code, k, 1], target, source, shift, True,
                    )  # fmt: skip
                    b = end
        else:  # runs across the lines, along memory
            for b in range(codes.shape[1]):
                a = 0
                while a < codes.shape[0]:
                    end = a + 1
                    while end < codes.shape[0] and codes[end, b] == codes[a, b]:
                        end += 1
                    top, bottom = a * block, min(end * block, lines)
                    left, right = b * width, min((b + 1) * width, n)
                    code = codes[a, b]
                    _lift_run(
                        x, top, bottom, left, right, slopes[code], sign * weights[code, k, 0],
                        sign * weights[code, k, 1], target, source, shift, False,
                    )  # fmt: skip
                    a = end


@njit(cache=True, nogil=True, inline="always")
def _lift_run(x, top, bottom, left, right, slope, c, e, target, source, shift, by_lines):
    """One step of :func:`_lift_along` on lines ``top:bottom``, samples ``left:right``, one slope,
    weights ``c`` (the neighbour before) and ``e`` (after)."""
    lines, n = x.shape[0], x.shape[1] // 2
    if c == 0.0 and e == 0.0:
        return
    # The neighbour at the line's end (predict: the last ``s``; update: the first ``d``) is mirrored.
    edge = n - 1 if shift == 1 else 0
    inner_left, inner_right = (left, min(right, n - 1)) if shift == 1 else (max(left, 1), right)
    if slope == 0.0 and c == e:  # the plain CDF 9/7 step, term by term as :func:`_step`
        if by_lines:
            for r in range(top, bottom):
                for j in range(inner_left, inner_right):
                    x[r, target + j] += c * (x[r, source + j] + x[r, source + j + shift])
        else:
            for j in range(inner_left, inner_right):
                for r in range(top, bottom):
                    x[r, target + j] += c * (x[r, source + j] + x[r, source + j + shift])
        if left <= edge < right:
            for r in range(top, bottom):
                x[r, target + edge] += c * (x[r, source + edge] + x[r, source + edge])
        return
    if slope == 0.0:  # one-sided weights straight across
        for j in range(left, right):
            p = source + (j if shift == 1 else max(j - 1, 0))
            q = source + (min(j + 1, n - 1) if shift == 1 else j)
            for r in range(top, bottom):
                x[r, target + j] += c * x[r, p] + e * x[r, q]
        return
    for r in range(top, bottom):
        u0, u1, f = _line_at(lines, r - slope)
        v0, v1, g = _line_at(lines, r + slope)
        for j in range(left, right):
            # Predict: s[k] before, s[k + 1] after; update: d[k - 1] before, d[k] after.
            p = source + (j if shift == 1 else max(j - 1, 0))
            q = source + (min(j + 1, n - 1) if shift == 1 else j)
            before = x[u0, p] + f * (x[u1, p] - x[u0, p])
            after = x[v0, q] + g * (x[v1, q] - x[v0, q])
            if c == e:
                x[r, target + j] += c * (before + after)
            else:
                x[r, target + j] += c * before + e * after


@kernel(*_layouts("void(X, i8[:, :], f8[:, :], i8, b1)"))
def _rescale(x, codes, scales, block, forward):
    """Multiply (``forward``; else divide) the low- and high-pass samples of every block of ``x``
    (split layout) by ``scales[code]`` of its code, skipping the codes scaled by ``(1, 1)``."""
    lines, n = x.shape[0], x.shape[1] // 2
    width = block // 2
    for a in range(codes.shape[0]):
        for b in range(codes.shape[1]):
            fs, fd = scales[codes[a, b], 0], scales[codes[a, b], 1]
            if fs == 1.0 and fd == 1.0:
                continue
            if not forward:
                fs, fd = 1.0 / fs, 1.0 / fd
            for r in range(a * block, min((a + 1) * block, lines)):
                for j in range(b * width, min((b + 1) * width, n)):
                    x[r, j] *= fs
                    x[r, n + j] *= fd


@kernel(*_layouts("void(X, i8, f8, f8[:, :])"))
def _high_pass_bits(x, block, threshold, costs):
    """Add ``log2(1 + 2 |d| / T)`` of every high-pass sample ``d`` of ``x`` (split layout) to
    ``costs`` of its block (see :func:`directional_pass`)."""
    lines, n = x.shape[0], x.shape[1] // 2
    width = block // 2
    scale = 2.0 / threshold
    for r in range(lines):
        for j in range(n):
            costs[r // block, j // width] += np.log2(1.0 + abs(x[r, n + j]) * scale)


def directional_pass(
    source: np.ndarray,
    target: np.ndarray,
    forward: bool,
    codes: np.ndarray,
    slopes: np.ndarray,
    weights: np.ndarray,
    scales: np.ndarray,
    block: int,
) -> None:
    """One lifting pass as :func:`cdf97_pass` (whole-sample symmetric extension), each block with
    its own four lifting steps, each reading the other half of the line along a slope
    (:mod:`bandelets.transform.directional`).

    Parameters
    ----------
    source, target : ndarray of float64, shape (lines, 2n)
        As :func:`cdf97_pass`.
    forward : bool
    codes : ndarray of int64, shape (ceil(lines / block), ceil(n / (block // 2)))
        Code of every block of ``block`` lines and ``block // 2`` samples of each half.
    slopes : ndarray of float64, shape (codes,)
        Slope of every code, in lines per sample.
    weights : ndarray of float64, shape (codes, 4, 2)
        Weights of the neighbour before and after of each of the four lifting steps of every
        code; ``(c, c)`` with the CDF 9/7 factors ``c`` and slope 0 are :func:`cdf97_pass` (the
        same numbers).
    scales : ndarray of float64, shape (codes, 2)
        Factors of the low- and high-pass samples of every code after the CDF 9/7 scaling.
    block : int
        Lines of a block (even).
    """
    by_lines = _by_lines(source)
    if forward:
        _split(source, target, by_lines, False)
        _lift_along(target, True, by_lines, codes, slopes, weights, block, 4)
        _normalise(target, by_lines, True)
        _rescale(target, codes, scales, block, True)
    else:
        _rescale(source, codes, scales, block, False)
        _normalise(source, by_lines, False)
        _lift_along(source, False, by_lines, codes, slopes, weights, block, 4)
        _merge(source, target, by_lines, False)


def direction_costs(
    source: np.ndarray,
    slopes: np.ndarray,
    weights: np.ndarray,
    scales: np.ndarray,
    block: int,
    threshold: float,
) -> np.ndarray:
    """``costs[i, a, b]``: the sum of ``log2(1 + 2 |d| / T)`` over the high-pass samples ``d``
    (before the final CDF 9/7 scaling, times ``scales[i, 1]``) of block ``a, b`` of
    :func:`directional_pass` of ``source`` with code ``i`` everywhere, ``T`` = ``threshold``."""
    lines, n = source.shape[0], source.shape[1] // 2
    split = np.empty((lines, 2 * n))
    _split(source, split, _by_lines(source), False)
    shape = (-(-lines // block), -(-n // (block // 2)))
    costs = np.zeros((len(slopes), *shape))
    trial = np.empty_like(split)
    for i in range(len(slopes)):
        trial[...] = split
        # The high-pass samples are final after the third step.
        _lift_along(trial, True, True, np.full(shape, i, np.int64), slopes, weights, block, 3)
        _high_pass_bits(trial, block, threshold / scales[i, 1], costs[i])
    return costs


@njit(cache=True, nogil=True, inline="always")
def _pair(a, b, haar, forward):
    """The two samples, or their Haar transform, as PyWavelets' filters compute it (the same
    numbers to the last bit): ``(r b + r a, -r b + r a)`` forward, ``(r a + r b, r a - r b)`` back."""
    if not haar:
        return a, b
    if forward:
        return _SQRT_HALF * b + _SQRT_HALF * a, -_SQRT_HALF * b + _SQRT_HALF * a
    return _SQRT_HALF * a + _SQRT_HALF * b, _SQRT_HALF * a + -_SQRT_HALF * b


@kernel(*_layouts("void(X, X, b1, b1)"))
def _split(source, target, by_lines, haar):
    """``target[:, :n] = source[:, 0::2]``, ``target[:, n:] = source[:, 1::2]`` (:func:`_pair` of them)."""
    lines, n = source.shape[0], source.shape[1] // 2
    if by_lines:
        for i in range(lines):
            for j in range(n):
                target[i, j], target[i, n + j] = _pair(source[i, 2 * j], source[i, 2 * j + 1], haar, True)
    else:
        for j in range(n):
            for i in range(lines):
                target[i, j], target[i, n + j] = _pair(source[i, 2 * j], source[i, 2 * j + 1], haar, True)


@kernel(*_layouts("void(X, X, b1, b1)"))
def _merge(source, target, by_lines, haar):
    """The inverse of :func:`_split`."""
    lines, n = source.shape[0], source.shape[1] // 2
    if by_lines:
        for i in range(lines):
            for j in range(n):
                target[i, 2 * j], target[i, 2 * j + 1] = _pair(source[i, j], source[i, n + j], haar, False)
    else:
        for j in range(n):
            for i in range(lines):
                target[i, 2 * j], target[i, 2 * j + 1] = _pair(source[i, j], source[i, n + j], haar, False)


@kernel(*_layouts("void(X, b1, b1)"))
def _normalise(x, by_lines, forward):
    """``s *= ZETA``, ``d /= ZETA`` (forward), or the other way round, as the numpy lifting did."""
    lines, n = x.shape[0], x.shape[1] // 2
    if by_lines:
        for i in range(lines):
            for j in range(n):
                x[i, j], x[i, n + j] = _scaled(x[i, j], x[i, n + j], forward)
    else:
        for j in range(n):
            for i in range(lines):
                x[i, j], x[i, n + j] = _scaled(x[i, j], x[i, n + j], forward)


@njit(cache=True, nogil=True, inline="always")
def _scaled(s, d, forward):
    # Divisions where the numpy lifting divided: x / ZETA and x * (1 / ZETA) may differ in the last bit.
    if forward:
        return s * ZETA, d / ZETA
    return s / ZETA, d * ZETA


_NO_FOLDS = (np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1))


def _by_lines(x: np.ndarray) -> bool:
    """Whether the lines of ``x`` run along memory (else: a column pass, on a transpose)."""
    return x.strides[1] <= x.strides[0]


def cdf97_pass(source: np.ndarray, target: np.ndarray, forward: bool, folds=None, spacing: int = 1) -> None:
    """One CDF 9/7 lifting pass along the second axis of ``source`` into ``target``.

    Parameters
    ----------
    source, target : ndarray of float64, shape (lines, 2n)
        Distinct blocks (views of a row-major array, or transposes of them). Forward: ``source``
        holds the interleaved samples (left as it is), ``target`` receives the low-pass
        coefficients times ``ZETA`` then the high-pass ones over ``ZETA``. Inverse: the other way
        round, ``source`` being overwritten.
    forward : bool
    folds : (first, second, weight), optional
        The spherical extension's mirror of every line (:func:`bandelets.transform.wavelets.spherical_folds`);
        None for the whole-sample symmetric extension.
    spacing : int
        Pixels between two samples of a line at this level (1 at the finest), for the spherical
        extension.
    """
    by_lines = _by_lines(source)
    spherical = folds is not None
    first, second, weight = folds if spherical else _NO_FOLDS
    if forward:
        _split(source, target, by_lines, False)
        _lift(target, True, by_lines, spherical, first, second, weight, spacing)
        _normalise(target, by_lines, True)
    else:
        _normalise(source, by_lines, False)
        _lift(source, False, by_lines, spherical, first, second, weight, spacing)
        _merge(source, target, by_lines, False)


@kernel(*_layouts("void(X, b1, f8)"))
def _box_predict(x, by_lines, sign):
    """``d_j += sign (s_(j+1) - s_(j-1)) / 8`` on every line of ``x`` (``s`` its first half, ``d`` its
    second), ``s`` extended by half-sample symmetry (``s_-1 = s_0``, ``s_n = s_(n-1)``)."""
    lines, n = x.shape[0], x.shape[1] // 2
    if by_lines:
        for i in range(lines):
            for j in range(n):
                x[i, n + j] += sign * (x[i, min(j + 1, n - 1)] - x[i, max(j - 1, 0)]) * 0.125
    else:
        for j in range(n):
            for i in range(lines):
                x[i, n + j] += sign * (x[i, min(j + 1, n - 1)] - x[i, max(j - 1, 0)]) * 0.125


def rbio13_pass(source: np.ndarray, target: np.ndarray, forward: bool) -> None:
    """One pass of the reverse biorthogonal 1.3 wavelet, as :func:`cdf97_pass`: the Haar pass of
    :func:`haar_pass` (low ``(a + b) sqrt(1/2)``, a box average: no update step), then the high pass
    predicted from the neighbouring low ones, ``d_j += (s_(j+1) - s_(j-1)) / 8``, which makes it blind
    to quadratics (PyWavelets' ``rbio1.3`` away from the border, with symmetric extension)."""
    by_lines = _by_lines(source)
    if forward:
        _split(source, target, by_lines, True)
        _box_predict(target, by_lines, 1.0)
    else:
        _box_predict(source, by_lines, -1.0)
        _merge(source, target, by_lines, True)


def haar_pass(source: np.ndarray, target: np.ndarray, forward: bool) -> None:
    """One Haar pass (periodic: no extension), as :func:`cdf97_pass`: low ``(a + b) sqrt(1/2)``,
    high ``(a - b) sqrt(1/2)`` of every pair ``a, b`` (rounded as PyWavelets does)."""
    (_split if forward else _merge)(source, target, _by_lines(source), True)


@kernel(*_layouts("void(X, i8, f8[:], b1)"))
def scale_subbands(c, levels, norms, inverse):
    """Multiply (``inverse``: divide) every subband of ``c`` (Mallat layout, ``levels`` levels) by
    its entry of ``norms``, in place: the approximation first, then H, V, D from the coarsest
    level (the order of :func:`bandelets.transform.wavelets.subband_slices`)."""
    rows, cols = c.shape
    for level in range(levels, -1, -1):
        h, w = rows >> max(level, 1), cols >> max(level, 1)
        if level == levels:  # the approximation
            _scale_block(c, 0, h, 0, w, norms[0], inverse)
        if level == 0:
            break
        base = 1 + 3 * (levels - level)
        _scale_block(c, 0, h, w, 2 * w, norms[base], inverse)
        _scale_block(c, h, 2 * h, 0, w, norms[base + 1], inverse)
        _scale_block(c, h, 2 * h, w, 2 * w, norms[base + 2], inverse)


@njit(cache=True, nogil=True)
def _scale_block(c, top, bottom, left, right, factor, inverse):
    for i in range(top, bottom):
        for j in range(left, right):
            c[i, j] = c[i, j] / factor if inverse else c[i, j] * factor
