"""Encoder-trained loop filter: a small Wiener filter the decoder applies after the restoration.

Not a step of the paper; the idea of VVC's adaptive loop filter and of AV1's Wiener loop
restoration. The encoder has both the original channels and the decoded (restored) ones, so it
can solve, by least squares, for the small linear filter that maps the decoded channels closest
to the original ones, and write that filter into the file (format version 11, the section of
:class:`bandelets.format.header.LoopFilter`). What is left after the restoration is mostly a smooth
loss of contrast of fine detail (a low-pass look) and a little ringing: a short symmetric filter
sharpens the one and damps the other, on every kind of content, without knowing which.

Each coded channel gets its own filter, of the form ``x + sum_k w_k (clip(x[p + k] - x[p]) +
clip(x[p - k] - x[p]))`` over the offsets ``k`` of a diamond of
:attr:`~bandelets.format.header.LoopFilter.radius` (point symmetric, so the filter has zero phase: 2,
6 or 12 taps; or, format version 12, of the 7 x 7 square, 24 taps), ``clip`` bounding each
difference to ``+-c`` (as VVC's non-linear ALF does: a difference across a crease or a bevel,
far above the quantization error, then weighs no more than one of ``c``, so the filter can
smooth the ringing beside a crease without blurring the crease itself; ``c = T 2**(3 - k)`` for
the :attr:`~bandelets.format.header.LoopFilter.clip` code ``k``, none for 0), plus, with
:attr:`~bandelets.format.header.LoopFilter.cross`, the same second differences of every other
channel over the 3 x 3 or (format version 12) the 5 x 5 square (4 or 12 taps each: the ``x`` of
a normal map has a say in its ``y``, the two being derivatives of one height; the wider square
sees the mixed derivatives of the other channel over more pixels). Written as corrections by
second differences, a constant image is left as it is and the rounding of the coefficients
(``k / 2**shift``) costs only where there is detail. Samples past the image's border are those
of the border (replicated), or, in a file whose image is folded (a normal map that is an
octahedral geometry image, :attr:`bandelets.format.header.Header.folded`, format version 14), those
across the folds: the border is then inside the surface, and the filter sees it so (+0.05 / +0.02
dB on fandisk / bunny's normal maps, 0.25 to 2 bpp, BENCHMARKS.md "Normal maps on octahedral
geometry images"). The filter reads and writes the ``H x W`` image, not the wavelet padding.

The encoder (:func:`choose`) accumulates the normal equations of the largest diamond shape at
each clipping of :data:`CLIPS` (one compiled pass each, on a regular sample of the rows of a large
image), solves those of every diamond shape (sub-matrices), rounds the coefficients at every
precision and keeps the clipping, shape and precision of least predicted ``error + LAMBDA T**2
bits`` (the rate-distortion trade-off of the rest of the encoder,
:data:`bandelets.search.lagrangian.LAMBDA`); the square shapes are fitted at that clipping only (one more
pass: on the acacia door they keep 0.17 of their 0.20 dB so, for a third of the time), then
applies that filter as the decoder will, measures the decoded image against the original with
the caller's measure and keeps it only if the measured error falls by more than ``LAMBDA T**2``
times its bits: it never writes a filter that measures worse than none at the price of its
bytes.

The clipping is what makes the filter pay on the real maps: on the lava map (fine bumps at
every scale) at 2 bpp, a 7 x 7 diamond gains 0.12 dB unclipped, 0.77 dB at ``c = T / 4``; on the
crease map at 0.35 bpp 0.49 dB unclipped, 0.61 dB at ``2 T``; the smooth bumps want none (0.91
dB unclipped, 0.15 at ``T / 4``): the encoder chooses (measured on the restored channels with
unrounded coefficients; BENCHMARKS.md, "Loop filter", has the files' figures and what lost).

Written here because the filter is a handful of compiled loops over the image (scipy's
``correlate`` would need a pass per tap and a copy per shifted channel, and clips nothing); the
normal equations are compiled products of the features (single-threaded, :func:`_gram`), the
least squares of at most 36 unknowns numpy's solve.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from itertools import pairwise

import numpy as np
from numba import njit

from ..format.fields import MAX_FILTER_SHIFT
from ..format.filter import (
    LoopFilter,
    filter_bytes,
    filter_cross_offsets,
    filter_offsets,
    filter_taps,
    filter_width,
)
from ..runtime.threads import CORES, thread_map

__all__ = [
    "SHAPES",
    "CLIPS",
    "SHIFTS",
    "FIT_PIXELS",
    "RESERVE_WIDTH",
    "apply",
    "clip_bound",
    "choose",
    "reserve",
]

#: Shapes the encoder tries, ``(radius, cross, square)``, those of cross-channel taps only within
#: :func:`_most_cross`: the 5 x 5 cross-channel square gains 0.06 to 0.4 dB over the 3 x 3 at the
#: price of its bytes (fitted, unrounded) on the real maps, the crease and the bevel map, the
#: 7 x 7 square of own taps another 0.2 dB on the acacia door (BENCHMARKS, "Loop filter").
SHAPES = ((2, 0, False), (3, 0, False), (3, 1, False), (3, 2, False), (3, 2, True))
#: Pixels the encoder fits the filter on, at least: every row of an image of up to that many, a
#: regular sample of the rows of a larger one (20 unknowns per channel at most).
FIT_PIXELS = 2**16
#: Clippings the encoder tries (:attr:`bandelets.format.header.LoopFilter.clip`): none, 4 T to T / 8.
CLIPS = (0, 1, 2, 3, 4, 5, 6)
#: Precisions the encoder tries: coefficients are multiples of ``2**-shift``.
SHIFTS = range(4, min(17, MAX_FILTER_SHIFT + 1))


def _table(radius: int, cross: int, square: bool, channels: int) -> np.ndarray:
    """The taps of one channel's filter as rows ``(channel offset, dy, dx)``: the diamond (or
    ``square``) of the channel itself (channel offset 0), then the square of radius ``cross`` of
    each other channel (channel offsets 1 to C - 1, the channel ``(c + offset) % C``)."""
    rows = [(0, dy, dx) for dy, dx in filter_offsets(radius, square)]
    rows += [(o, dy, dx) for o in range(1, channels) for dy, dx in filter_cross_offsets(cross)]
    return np.array(rows, np.int64).reshape(-1, 3)


@njit(cache=True, nogil=True, inline="always")
def _clipped(d, bound):
    """``d`` within ``[-bound, bound]`` (``bound`` may be infinite)."""
    return min(max(d, -bound), bound)


@njit(cache=True, nogil=True, inline="always")
def _feature(x, c, o, dy, dx, i, j, rows, cols, channels, bound, folded):
    """The clipped second difference ``clip(x[p + k] - x[p]) + clip(x[p - k] - x[p])`` of the
    channel ``(c + o) % C`` at ``p = (i, j)``, ``k = (dy, dx)``, the border replicated, or
    (``folded``) the samples past it those across the folds (:func:`_across`)."""
    k = (c + o) % channels
    if folded:
        i1, j1 = _across(i + dy, j + dx, rows, cols)
        i2, j2 = _across(i - dy, j - dx, rows, cols)
    else:
        i1, j1 = min(max(i + dy, 0), rows - 1), min(max(j + dx, 0), cols - 1)
        i2, j2 = min(max(i - dy, 0), rows - 1), min(max(j - dx, 0), cols - 1)
    v = x[k, i, j]
    return _clipped(x[k, i1, j1] - v, bound) + _clipped(x[k, i2, j2] - v, bound)


@njit(cache=True, nogil=True, inline="always")
def _across(i, j, rows, cols):
    """The pixel at ``(i, j)``, past the border of an octahedral geometry image, glued across each
    edge to itself reversed: row ``-k`` is row ``k - 1`` mirrored, and so on.

    A pixel at most a side past the border is inside after one fold; one farther (a filter wider
    than the image, which a hostile file may ask for: a 2 x 2 map with a filter of radius 3) is
    folded again until it is: each fold brings the row (column) nearer the image by its side and
    leaves the other coordinate as far past as it was, so the loop ends, and every index the
    compiled filter reads is in the image (issue 40)."""
    while True:
        if i < 0:
            i, j = -1 - i, cols - 1 - j
        elif i >= rows:
            i, j = 2 * rows - 1 - i, cols - 1 - j
        if j < 0:
            i, j = rows - 1 - i, -1 - j
        elif j >= cols:
            i, j = rows - 1 - i, 2 * cols - 1 - j
        if 0 <= i < rows and 0 <= j < cols:
            return i, j


@njit(cache=True, nogil=True)
def _features(x, c, table, bound, start, stop, stride, out, folded):
    """The features of channel ``c`` (:func:`_feature`) at the pixels of the rows ``start`` to
    ``stop`` by ``stride``, one column of ``out`` (taps x pixels) per pixel, in row order: along
    each row tap by tap inside (loops the compiler vectorises), pixel by pixel on the border."""
    channels, rows, cols = x.shape
    n = table.shape[0]
    r = 0
    for t in range(n):
        r = max(r, abs(table[t, 1]), abs(table[t, 2]))
    for row, i in enumerate(range(start, stop, stride)):
        p = row * cols
        inside = r <= i < rows - r
        if inside:
            for t in range(n):
                k, dy, dx = (c + table[t, 0]) % channels, table[t, 1], table[t, 2]
                above, middle, below, f = x[k, i + dy], x[k, i], x[k, i - dy], out[t, p : p + cols]
                for j in range(r, cols - r):
                    v = middle[j]
                    f[j] = _clipped(above[j + dx] - v, bound) + _clipped(below[j - dx] - v, bound)
        for j in range(cols):
            if inside and r <= j < cols - r:
                continue
            for t in range(n):
                out[t, p + j] = _feature(
                    x, c, table[t, 0], table[t, 1], table[t, 2], i, j, rows, cols, channels, bound, folded
                )


def _normal_equations(x, residual, table, bound, stride, folded):
    """``gram[c] = A_c' A_c`` and ``moment[c] = A_c' residual_c``, shapes (C, n, n) and (C, n),
    with ``A_c`` the features of channel ``c`` of ``x`` at the pixels of every ``stride``-th row
    (``residual``: the target minus ``x`` at those rows, shape (C, rows, W)), scaled as if from
    every row: products of ``A_c'`` and the residual by their transpose (:func:`_gram`), a block of
    rows at a time (:data:`_BLOCK` pixels)."""
    channels, rows, cols = x.shape
    n = len(table)
    block = max(1, _BLOCK // cols)  # sampled rows a block
    f = np.empty((n + 1, block * cols))
    total = np.zeros((channels, n + 1, n + 1))
    for c in range(channels):
        for first in range(0, residual.shape[1], block):
            count = min(block, residual.shape[1] - first) * cols
            _features(
                x, c, table, bound, first * stride, min(rows, (first + block) * stride), stride, f, folded
            )
            f[n, :count] = residual[c, first : first + block].ravel()
            _gram(f, count, total[c])
    return total[:, :n, :n] * stride, total[:, :n, n] * stride


@njit(cache=True, nogil=True, fastmath=True)
def _gram(f, count, out):
    """``out += f[:, :count] f[:, :count]'`` (``out`` symmetric), compiled and single-threaded.

    Not numpy's product: OpenBLAS runs it on its own threads, which stall on a loaded machine (a
    block of 37 rows, the 7 x 7 square and the other channel's 5 x 5: 15 ms, for 1.4 ms in one
    thread, on the 2-core machine shared, issue 36). Two rows by two at a time (four sums from
    four loads): as fast as one thread of OpenBLAS, 0.04 to 0.8 ms a block of 7 to 37 rows
    (0.05 to 1.8 ms row by row)."""
    n = f.shape[0]
    for i in range(0, n, 2):
        i2 = min(i + 1, n - 1)  # the last row of an odd count is paired with itself
        a, a2 = f[i], f[i2]
        for j in range(i, n, 2):
            j2 = min(j + 1, n - 1)
            b, b2 = f[j], f[j2]
            s11 = s12 = s21 = s22 = 0.0
            for k in range(count):
                s11 += a[k] * b[k]
                s12 += a[k] * b2[k]
                s21 += a2[k] * b[k]
                s22 += a2[k] * b2[k]
            # The upper triangle, each entry once.
            out[i, j] += s11
            if j2 != j:
                out[i, j2] += s12
            if i2 != i and j >= i2:
                out[i2, j] += s21
            if i2 != i and j2 != j:
                out[i2, j2] += s22
    for i in range(n):
        for j in range(i + 1, n):
            out[j, i] = out[i, j]


#: Pixels of a block of the normal equations (:func:`_normal_equations`): 1.4 MB of features.
_BLOCK = 2**13


@njit(cache=True, nogil=True)
def _apply(x, table, weights, bound, out, first, last, folded):
    """``out[c] = x[c] + sum_t weights[c, t] feature_t`` (float64) over the rows ``first`` to
    ``last``, the taps in the order of ``table`` (:func:`_feature`): inside, tap by tap along each
    row (loops the compiler vectorises), on the border pixel by pixel; the same numbers either way."""
    channels, rows, cols = x.shape
    n = table.shape[0]
    r = 0
    for t in range(n):
        r = max(r, abs(table[t, 1]), abs(table[t, 2]))
    s = np.empty(cols)
    for c in range(channels):
        for i in range(first, last):
            inside = r <= i < rows - r
            if inside:
                s[:] = 0.0
                for t in range(n):
                    k, dy, dx, w = (c + table[t, 0]) % channels, table[t, 1], table[t, 2], weights[c, t]
                    above, middle, below = x[k, i + dy], x[k, i], x[k, i - dy]
                    for j in range(r, cols - r):
                        v = middle[j]
                        s[j] += w * (_clipped(above[j + dx] - v, bound) + _clipped(below[j - dx] - v, bound))
                for j in range(r, cols - r):
                    out[c, i, j] = x[c, i, j] + s[j]
            for j in range(cols):
                if inside and r <= j < cols - r:
                    continue
                acc = 0.0
                for t in range(n):
                    acc += weights[c, t] * _feature(
                        x, c, table[t, 0], table[t, 1], table[t, 2], i, j, rows, cols, channels, bound, folded
                    )
                out[c, i, j] = x[c, i, j] + acc


def apply(
    channels: np.ndarray,
    loop_filter: LoopFilter,
    threshold: float,
    height: int,
    width: int,
    folded: bool = False,
) -> np.ndarray:
    """The filtered image: ``channels`` (C, H', W'), padded, filtered over their first ``height``
    rows and ``width`` columns (``threshold``: the file's ``T``, the unit of the clipping;
    ``folded``: the samples past the border are those across the folds, see the module's docstring).

    Returns
    -------
    ndarray of float64, shape (C, height, width)
    """
    x = np.ascontiguousarray(channels[:, :height, :width], dtype=np.float64)
    table = _table(loop_filter.radius, loop_filter.cross, loop_filter.square, x.shape[0])
    weights = np.array(loop_filter.coefficients, np.float64).reshape(x.shape[0], -1) / 2.0**loop_filter.shift
    out = np.empty_like(x)
    bound, rows = clip_bound(loop_filter.clip, threshold), x.shape[1]
    if CORES == 1 or rows * x.shape[2] < THREADED_PIXELS:
        _apply(x, table, weights, bound, out, 0, rows, folded)
        return out
    # Bands of rows in threads (the kernel releases the GIL; every pixel is computed on its own).
    edges = np.linspace(0, rows, min(CORES, 8) + 1).astype(int)
    with ThreadPoolExecutor(len(edges) - 1, thread_name_prefix="bandelets-loop-filter") as pool:
        for done in [
            pool.submit(_apply, x, table, weights, bound, out, a, b, folded) for a, b in pairwise(edges)
        ]:
            done.result()
    return out


#: Pixels of a channel from which :func:`apply` filters bands of rows in threads: at 2048 x 2048
#: with the 7 x 7 square and the other channel's 5 x 5, 0.56 s in one thread (2-core machine).
THREADED_PIXELS = 256 * 256


def clip_bound(code: int, threshold: float) -> float:
    """The bound of the differences for the clipping ``code`` (0: none, infinite)."""
    return float("inf") if code == 0 else threshold * 2.0 ** (3 - code)


#: Bits per coefficient a rate target leaves room for (:func:`reserve`).
RESERVE_WIDTH = 9


def reserve(channels: int) -> int:
    """Bytes a rate target leaves free for the loop filter of ``channels`` channels: its largest
    shape at :data:`RESERVE_WIDTH` bits a coefficient (:func:`bandelets.search.ratecontrol.for_size`
    caps it at half its tolerance)."""
    shapes = [shape for shape in SHAPES if shape[1] <= _most_cross(channels)]
    return max(filter_bytes(channels, _taps(shape, channels), RESERVE_WIDTH) for shape in shapes)


def _most_cross(channels: int) -> int:
    """The widest cross-channel square the encoder tries for ``channels`` channels: the 5 x 5 for
    two (a normal map's equidistant coordinates, where it was measured), the 3 x 3 for three."""
    return {2: 2, 3: 1}.get(channels, 0)


def _taps(shape: tuple[int, int, bool], channels: int) -> int:
    radius, cross, square = shape
    return filter_taps(radius, cross, channels, square)


def choose(
    channels: np.ndarray,
    target: np.ndarray,
    threshold: float,
    lam: float,
    error: Callable[[np.ndarray], float],
    budget: int | None = None,
    folded: bool = False,
) -> tuple[LoopFilter | None, np.ndarray | None]:
    """The filter of least ``error + lam T**2 bits``, or none.

    Every shape of :data:`SHAPES` is fitted from one set of normal equations per clipping of
    :data:`CLIPS` (those of the largest shape, whose taps hold the others'), on a regular sample
    of the rows (:data:`FIT_PIXELS`); the clipping, shape and precision of least predicted cost
    are applied and measured by ``error`` against the unfiltered channels: the filter is kept only
    if the measured error falls by more than the price of its bytes.

    Parameters
    ----------
    channels : ndarray, shape (C, H', W')
        The decoded channels (restored), padded.
    target : ndarray, shape (C, H, W)
        What they stand for: the original channels.
    threshold, lam : float
        ``T`` and the Lagrange multiplier of the encoder (bits are priced ``lam T**2`` each).
    error : callable
        ``(C, H, W)`` (or padded) channels to the squared error of the image they decode to,
        summed, in the units of ``T**2``: the measure the choice trusts.
    budget : int, optional
        Most bytes the filter section may take.
    folded : bool
        The image is folded (see the module's docstring): the samples past its border are those
        across the folds.

    Returns
    -------
    loop_filter : LoopFilter or None
    filtered : ndarray (C, H, W) or None
        The filtered channels (None without a filter).
    """
    count, height, width = target.shape
    x = np.ascontiguousarray(channels[:, :height, :width], dtype=np.float64)
    price = lam * threshold**2
    shapes = [shape for shape in SHAPES if shape[1] <= _most_cross(count)]
    stride = max(1, height * width // FIT_PIXELS)
    residual = target[:, ::stride] - x[:, ::stride]  # float64, as x
    fit = partial(
        _proposal, x, residual, threshold=threshold, stride=stride, price=price, budget=budget, folded=folded
    )
    proposal, proposal_cost = None, 0.0
    plain = [shape for shape in shapes if not shape[2]]
    # The clippings in threads, in order (independent fits, nogil kernels): on two cores the fit
    # takes half the wall time.
    for cost, found in thread_map(lambda clip: fit(plain, clip), CLIPS, min(CORES, 2)):
        if cost < proposal_cost:
            proposal_cost, proposal = cost, found
    squares = [shape for shape in shapes if shape[2]]
    if proposal is not None and squares:
        cost, found = fit(squares, proposal[1])
        if cost < proposal_cost:
            proposal_cost, proposal = cost, found
    if proposal is None:
        return None, None
    (radius, cross, square), clip, shift, q, bits = proposal
    found = LoopFilter(
        radius=radius,
        cross=cross,
        square=square,
        clip=clip,
        shift=shift,
        coefficients=tuple(q.ravel().tolist()),
    )
    out = apply(x, found, threshold, height, width, folded)
    if error(out) + price * bits >= error(x):
        return None, None
    return found, out


def _proposal(x, residual, shapes, clip, *, threshold, stride, price, budget, folded):
    """The least predicted cost (below 0) of the ``shapes`` at ``clip`` and its ``(shape, clip,
    shift, integers, bits)`` (None if none is below 0), from the normal equations of the largest."""
    count = x.shape[0]
    full = _table(*max(shapes, key=lambda shape: _taps(shape, count)), count)
    rows = [tuple(r) for r in full.tolist()]
    gram, moment = _normal_equations(x, residual, full, clip_bound(clip, threshold), stride, folded)
    best, best_cost = None, 0.0
    for shape in shapes:
        pick = [rows.index(tuple(r)) for r in _table(*shape, count).tolist()]
        g, m = gram[:, pick][:, :, pick], moment[:, pick]
        # A touch of ridge: a flat image (no detail at all) has a singular system.
        ridge = 1e-9 * np.trace(g, axis1=1, axis2=2)[:, None, None] / len(pick) + 1e-300
        w = np.linalg.solve(g + ridge * np.eye(len(pick)), m[..., None])[..., 0]
        rounded = _rounded(w, g, m, price, budget)
        if rounded is not None and rounded[0] < best_cost:
            best_cost, best = rounded[0], (shape, clip, *rounded[1:])
    return best_cost, best


def _rounded(w, gram, moment, price, budget):
    """The precision of least predicted ``change of the error + price bits`` for the coefficients
    ``w`` (C, n) and the normal equations ``gram``, ``moment``: that cost, the shift, the rounded
    coefficients (integers, shape (C, n)) and the section's bits; None if no precision lowers the
    cost below 0 (no filter) within the budget."""
    channels, n = w.shape
    best, best_cost = None, 0.0
    for shift in SHIFTS:
        q = np.rint(w * 2.0**shift)
        size = filter_bytes(channels, n, filter_width(int(np.max(np.abs(q)))))
        if budget is not None and size > budget:
            continue
        v = q / 2.0**shift
        # The change of the squared error with the correction A v: v'Gv - 2 v'm per channel.
        change = float(np.einsum("ci,cij,cj->", v, gram, v) - 2.0 * np.sum(v * moment))
        cost = change + price * 8 * size
        if cost < best_cost:
            best, best_cost = (cost, shift, q.astype(np.int64), 8 * size), cost
    return best
