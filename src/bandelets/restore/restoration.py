"""Decoder-side restoration: a decoded image with sparser gradients, consistent with the file.

Not a step of the paper. Dequantizing each coefficient to one point of its bin (step (8))
leaves ringing along every crease: that is most of the error of a wavelet coder, bandelets
included, on CAD normal maps. But the file says more than those points: each coefficient
lies somewhere in its quantization bin. Among all images whose bandelet coefficients fall in
their bins (all equally consistent with the file), a piecewise smooth surface is better
guessed by one whose gradient is sparse: flat or smooth almost everywhere, with a few sharp
creases (consistent reconstruction, in the spirit of Durand and Froment's total-variation
reconstruction of wavelet coefficients, 2003). So the decoder alternates a gradient step on
a sparsity penalty of the image gradient, coupled over the channels so that the creases of
all channels stay at the same place, with the projection of every coefficient back into its
bin, starting from the plain dequantized image, with momentum.

The penalty is a log total variation, ``sum e log(1 + |grad x| / e)`` with ``e = EDGE T``
(the total variation reweighted by ``e / (e + |grad x|)``, as in Candes, Wakin and Boyd's
reweighted l1): small gradients, the ringing, are flattened as by the total variation, while
gradients well above ``e``, the creases, are hardly touched. On the crease map this restores
0.8 to 2.1 dB more than the plain total variation at 0.25 to 2 bpp. Alone it would also flatten
the gentle slopes of fillets and bumps into staircases; a second term, the same log penalty on
the second differences (``|d2x/du2|, |d2x/dv2|`` and ``sqrt(2) |d2x/dudv|``, joint over the
channels, weight :data:`SECOND_ORDER`, corner :data:`SECOND_EDGE` T), prefers slopes that
stay constant between creases, and lets the first term's corner drop from 0.5 T to
:data:`EDGE` = 0.15 T. Together they restore 0.7 dB BD more than the first term alone on the
crease map, 0.6 dB more on fandisk's normal map and 0.3 dB more on the bumps
(``python benchmarks/restoration_gain.py``, and with ``--second-order 0 --edge 0.5`` for the
first term alone, ``--second-order 0 --edge 1e9`` for the total variation).

How many steps is the encoder's choice: it runs the same iterations, measures the error
against the original after each, and writes into the file the fewest iterations that keep 97 %
of the best gain (:data:`bandelets.codec.encoder.RESTORATION_SHARE`, format version 10; 0: off, e.g.
on smooth surfaces, where there is nothing to sharpen). It costs no bits and, since the encoder
measures before it chooses, never decodes worse than plain dequantization.

The projection into the bins (an analysis and a synthesis of every channel, two thirds of an
iteration's cost) is done every :data:`PROJECT_EVERY` = 10 iterations only (format version 9):
within the few dozen steps the encoder picks, the penalty's steps hardly ever push a coefficient
out of its bin, so the projection need not follow each of them. The gain is kept, in a third of
the time (``python benchmarks/restoration_gain.py --project-every N``, BD-PSNR of the
restoration on crease / bumps / fandisk normals: +3.99 / +0.48 / +2.28 dB projecting at every
step, +4.04 / +0.48 / +2.41 every 5, +4.02 / +0.48 / +2.27 every 10, +3.91 / +0.48 / - every 20,
+3.74 / +0.47 / - never). A larger step with it, 0.015 T, takes 20 % fewer iterations but
loses 0.1 dB on the crease map (+3.89 / +0.47 / +2.31 dB): not taken.

An iteration is one pass over the image (format version 10, :func:`_rows`): the differences of a
row, their weights and what its stencils spread to the rows above and below are made a row ahead
into rings of four rows that stay in the cache, in float32 and in units of the smoothing (the
gradient is the same when the samples and the constants are scaled together, so float32 meets
neither overflow nor underflow whatever the threshold), and the step, the renormalisation and the
momentum follow row by row; the images between the steps are float32 where the samples are small
against ``T`` (:data:`SINGLE_UP_TO`). The restored images differ from version 9's in their last
digits only (+4.12 / +0.49 dB on crease / bumps either way, ``benchmarks/restoration_gain.py``),
in 0.7 times the CPU time at 512 x 512 for as many iterations (BENCHMARKS.md, "Decoder-side
restoration").

On an octahedral geometry image (the file's spherical extension,
:func:`bandelets.transform.wavelets.spherical_folds`)
the image is glued across each edge to itself turned by half a turn: the penalty's first term also takes
the difference of every border pixel with its neighbour across the edge (``folded``), where it would
otherwise see no neighbour. Measured on fandisk / bunny's geometry images (256 x 256, ``restore=True``,
0.25 to 2 bpp, same files): +0.018 / +0.003 dB PSNR of the positions on average, +0.04 / +0.02 dB at
0.25 bpp. Forced onto the normal maps of the same meshes (octahedral images too, but coded as normal maps
with the symmetric extension, so nothing in their files says so), it would restore +0.10 / +0.03 dB more
(``benchmarks/restoration_variants.py --maps fandisk,bunny``, +0.18 dB at 0.25 bpp on fandisk). A
second-order term at the border with the whole-sample symmetric extension of the wavelets (``xx = 2 dx``
on the border) lost there: -0.06 / -0.02 dB (it pulls the slope at the border to 0, the second
differences' free end, 0 on the border, is kept). Since format version 14 the normal maps that are
octahedral geometry images say so (:attr:`bandelets.format.header.Header.folded`) and are restored across
their folds too, and their second-order term also takes, centred on every border pixel, the second
difference through its neighbour across the fold and the one inside (``second_across``, a term of its
own, joint over the channels): on the same files of fandisk / bunny's normal maps (0.25 to 2 bpp) the
restored PSNR is +0.069 / +0.026 dB with the first-order folds, +0.099 / +0.044 dB with both (+0.23 /
+0.09 dB at 0.25 bpp; BENCHMARKS.md, "Normal maps on octahedral geometry images"). Not on the
geometry images: coded with the spherical extension, their border is already coded across the folds,
and the second differences there lose (restoration gain of the positions of fandisk / bunny, 0.25 to 2
bpp: 1.266 -> 1.199 / 0.574 -> 0.553 dB).

Written here (compiled loops for the gradient, the steps, the renormalisation and the projection
into the bins) because no library offers such a reconstruction constrained in an arbitrary (here
bandelet) basis: scikit-image's and scipy's total-variation denoisers solve the unconstrained
problem in the pixel domain.

Faster solvers were measured and lost (BD-PSNR of the restoration as above, projecting at every
step): larger steps keep less of the gain at low rates (``python benchmarks/restoration_gain.py
--step 0.015``: +3.87 / +0.48 dB on crease / bumps in 20 % fewer iterations; 0.02 T: +3.78 /
+0.47 / +2.48 against +4.01 / +0.49 / +2.59 in an earlier run). Prototypes (environment
switches, not kept): restarting the momentum when it turns against the step (O'Donoghue and
Candes) changed nothing at 0.015 T and gave +3.75 / +0.47 / +2.17 at 0.02 T, +3.53 / +0.45 /
+2.07 at 0.03 T; steps growing with the iteration count (0.01 T times ``min(3, 1 + k / 20)``)
+3.73 / +0.48 / +2.16; a step preconditioned by the diagonal of the reweighted penalty (Jacobi,
0.3 over that diagonal) +0.51 dB on crease, and capped at 0.03 T +3.62 / +0.41. The path, not
only where it ends, is what the encoder's choice of the count regularises.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from itertools import count

import numpy as np
from numba import njit

from ..format.quantizer import clip_into_bins, dequantize
from ..runtime.threads import CORES, workers
from .penalty import across_folds, log_weight, scaled, second_across_folds

__all__ = [
    "STEP",
    "SMOOTHING",
    "EDGE",
    "SECOND_ORDER",
    "SECOND_EDGE",
    "PROJECT_EVERY",
    "penalty_gradient",
    "iterate",
]

#: Gradient step on the penalty, in units of ``T`` per iteration (each sample moves by
#: at most about 4 STEP T per step): small enough that the count chosen by the encoder is not
#: a knife edge, large enough to converge in a few dozen iterations.
STEP = 0.01
#: Smoothing of the penalty's corner, ``|grad|`` stands for ``sqrt(|grad|**2 + (SMOOTHING T)**2)``.
SMOOTHING = 0.01
#: Gradient magnitude, in units of ``T``, above which the penalty grows only logarithmically:
#: what is sharper is taken for a crease and kept.
EDGE = 0.15
#: Weight of the log penalty on the second differences, relative to the one on the gradient.
SECOND_ORDER = 0.25
#: Second-difference magnitude, in units of ``T``, above which that penalty grows only
#: logarithmically (the kink of a crease).
SECOND_EDGE = 0.5
#: Iterations per projection into the bins (the others take the penalty's step alone).
PROJECT_EVERY = 10
#: The images the steps make are float32 (half the memory each step reads and writes) where the
#: samples' largest magnitude is at most this many times ``T``, with ``T`` from 2**-64 to 2**64
#: (far within float32's range, differences and step included): their rounding, at most
#: ``T / 2**10``, stays far below the moves of a step (a hundredth of ``T``); float64 otherwise
#: (extreme thresholds, large values).
SINGLE_UP_TO = 2.0**14
#: Largest difference, in units of the smoothing, that the penalty's float32 arithmetic takes (larger
#: ones are clamped to it: a crease whatever its height, weighted about 0): squared and summed over
#: the channels, it stays far below float32's largest value.
_LARGEST = 1e15
#: Below this length a vector is left as it is rather than blown up to unit length.
_SHORTEST = 1e-6
#: Pixels from which an iteration (and :func:`penalty_gradient`) computes the two halves of the rows
#: in two threads: with format version 9's kernel at 128^2 x 3 already 0.29 ms against 0.36 in one,
#: at 512^2 2.9 ms against 5.0 (2-core machine).
THREADED_SAMPLES = 128 * 128


def penalty_gradient(
    x: np.ndarray,
    smoothing: float,
    edge: float,
    second_order: float = 0.0,
    second_edge: float = 1.0,
    out: np.ndarray | None = None,
    folded: bool = False,
    second_across: bool = False,
) -> np.ndarray:
    """Gradient of the restoration penalty: a vectorial log total variation
    ``sum edge log(1 + n / edge)``, where ``n = sqrt(sum_c |grad x_c|**2 + smoothing**2)`` at every
    pixel, plus ``second_order`` times the same log penalty (corner ``second_edge``) on the norm of
    the second differences ``sqrt(sum_c xx_c**2 + yy_c**2 + 2 xy_c**2 + smoothing**2)``.

    Forward differences for the gradient, zero past the last row and column; centred second
    differences ``xx``, ``yy`` (zero on the border rows and columns) and the forward mixed one
    ``xy`` (zero on the last row and column). For ``n`` much below ``edge`` the first term is the
    total variation; above, its pull fades as ``edge / n``.

    Parameters
    ----------
    x : ndarray, shape (C, H, W), H, W >= 2
        Channels; their differences share one norm per pixel (one crease for all channels).
    smoothing, edge, second_edge : float
        > 0, in the units of ``x``.
    second_order : float
        >= 0; 0 leaves the second-order term out.
    out : ndarray, shape (C, H, W), float64, row-major, optional
        Where to write the gradient (not ``x``).
    folded : bool
        ``x`` is an octahedral geometry image, glued across each edge to itself turned by half a
        turn about the edge's midpoint (:func:`bandelets.transform.wavelets.spherical_folds`): each border
        pixel also has a neighbour across the edge (the pixel ``(0, W - 1 - j)`` for ``(0, j)``,
        ``(H - 1 - i, 0)`` for ``(i, 0)``, the same on the other edges), and each such pair adds a
        term ``edge log(1 + n / edge)`` with ``n = sqrt(sum_c (x_c - y_c)**2 + smoothing**2)``.
    second_across : bool
        With ``folded``, each border pixel ``p`` (each corner twice, once per edge) also adds
        ``second_order`` times the term of corner ``second_edge`` of the second difference through
        it, ``y - 2 p + z``, ``y`` its neighbour across the edge and ``z`` the one inside (format
        version 14, normal maps).

    Notes
    -----
    Computed in float32 (relative precision about 1e-7), in units of ``smoothing``. From
    :data:`THREADED_SAMPLES` pixels on, the two halves of the rows are computed in two threads
    (the same numbers as in one).

    Returns
    -------
    ndarray, shape (C, H, W)
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    out = np.empty_like(x) if out is None else out
    folds = _folds(folded, second_across)
    _in_halves(x, (smoothing, edge, second_order, second_edge), -1.0, out, out, 0.0, 0, 0, folds)
    return out


def _folds(folded: bool, second_across: bool) -> int:
    """The terms across the folds :func:`_rows` adds: 0 none, 1 the first differences, 2 the second
    ones too."""
    return int(folded) + int(folded and second_across)


def _in_halves(x, constants, step, out, previous, weight, unit_rows, unit_cols, folds=0) -> None:
    """:func:`_rows` over all the rows of ``x``: in two threads, a half of the rows each, from
    :data:`THREADED_SAMPLES` pixels on (each row is the same numbers whichever thread computes it);
    ``folds``: :func:`_folds`."""
    rows, cols = x.shape[1:]
    smoothing, edge, second_order, second_edge = (float(c) for c in constants)
    # In units of the smoothing (the gradient does not change when x and the constants are scaled
    # together): the float32 arithmetic meets neither overflow nor underflow, whatever the threshold.
    scaled = (np.float32(edge / smoothing), np.float32(second_order), np.float32(second_edge / smoothing))
    # The differences and the step in the images' type (float32 images: twice the samples to a vector).
    real = x.dtype.type
    args = (x, real(1.0 / smoothing), real(_LARGEST), *scaled, real(step), out, previous, real(weight))
    args = (*args, int(unit_rows), int(unit_cols), int(folds))
    if rows * cols < THREADED_SAMPLES or rows < 8 or CORES < 2:
        _rows(*args, 0, rows)
        return
    half = rows // 2
    future = workers().submit(_rows, *args, half, rows)
    _rows(*args, 0, half)
    future.result()


@njit(cache=True, nogil=True, error_model="numpy")
def _rows(
    x,
    scale,
    largest,
    edge,
    second_order,
    second_edge,
    step,
    out,
    previous,
    weight,
    unit_rows,
    unit_cols,
    folds,
    start,
    stop,
):
    """The rows ``start`` to ``stop`` of the penalty's gradient at ``x`` (``step`` < 0), or of a whole
    iteration (``step`` >= 0): ``out = x - step gradient``, brought to unit length on the first
    ``unit_rows`` rows and ``unit_cols`` columns, then (``weight`` >= 0) ``previous = out + weight
    (out - previous)``, in place; other rows of ``out`` and ``previous`` are left untouched.
    ``scale``: the inverse of the smoothing, ``largest``: :data:`_LARGEST`, ``step``, ``weight``:
    of the type of ``x``; ``edge``, ``second_order``, ``second_edge``: float32, the first and last
    in units of the smoothing; ``folds``: the terms across the folds (:func:`_folds`).

    One pass over the image: what a row's stencils reach in the rows above and below (the weighted
    differences, :func:`_row_terms`) is made a row ahead into rings of four rows, so what they read
    and write stays in the cache. The differences, their weights and the gradient are float32 (twice
    the pixels per instruction of float64; a relative precision of 6e-8 on the gradient, which
    moves the samples by a hundredth of the threshold per step), the step of the type of ``x``.
    Every sample is the same numbers, added in the same order, whatever ``start`` and ``stop`` (the
    rows past them are made again, not shared), and without a branch inside the image."""
    channels, rows, cols = x.shape
    ring = np.empty((6, channels, 4, cols), np.float32)
    px, py, a, b, d, dy = ring[0], ring[1], ring[2], ring[3], ring[4], ring[5]
    s, w, g = np.empty(cols, np.float32), np.empty(cols, np.float32), np.empty((channels, cols), np.float32)
    constants = (scale, largest, edge, second_order, second_edge, second_order > 0.0)
    first = max(start - 1, 0)
    if first > 0:  # the row above the first one made, for its second differences
        _vertical(x, first - 1, scale, largest, dy[:, (first - 1) % 4])
    for r in range(first, min(start + 1, rows)):
        _row_terms(x, r, *constants, s, w, px, py, a, b, d, dy)
    for i in range(start, stop):
        if i + 1 < rows:
            _row_terms(x, i + 1, *constants, s, w, px, py, a, b, d, dy)
        for c in range(channels):
            _divergence_row(i, rows, px[c], py[c], a[c], b[c], d[c], constants[-1], g[c])
        if folds:
            across_folds(x, i, scale, largest, edge, g)
            if folds == 2 and second_order > 0.0:
                second_across_folds(x, i, scale, largest, second_order, second_edge, g)
        if step < 0.0:
            for c in range(channels):
                out[c, i] = g[c]
            continue
        for c in range(channels):
            v, o, gc = x[c, i], out[c, i], g[c]
            for j in range(cols):
                o[j] = v[j] - gc[j] * step
        if i < unit_rows:
            _to_unit_length(out, i, unit_cols)
        if weight >= 0.0:
            for c in range(channels):
                o, p = out[c, i], previous[c, i]
                for j in range(cols):
                    p[j] = (o[j] - p[j]) * weight + o[j]


@njit(cache=True, nogil=True, error_model="numpy")
def _row_terms(x, r, scale, largest, edge, second_order, second_edge, second, s, w, px, py, a, b, d, dy):
    """Row ``r`` (into the ring row ``r % 4``), channel by channel, of the forward differences (0 past
    the end) times the weight of the joint gradient, ``px`` and ``py``, and, with ``second``, of what
    each pixel's second differences spread to its neighbours: ``a = w xx``, ``b = w yy``,
    ``d = 2 w xy``, with ``w`` ``second_order`` times the weight of the joint second differences.
    In units of the smoothing (``scale``: its inverse; at most ``largest``); ``dy``: the vertical
    differences, which need to be there for the row above (:func:`_vertical`); ``s`` and ``w``:
    scratch rows. Loops that each write one row, which the compiler vectorises.

    The second differences are differences of the first ones (in float32: their error, 6e-8 times
    the slope, is far below the smoothing wherever the second-order term has a say); ``a`` holds
    the row's ``dx`` until ``xx`` replaces it."""
    channels, rows, cols = x.shape
    k = r % 4
    _vertical(x, r, scale, largest, dy[:, k])
    for c in range(channels):
        here, dx = x[c, r], a[c, k]
        for j in range(cols - 1):
            dx[j] = scaled(here[j + 1] - here[j], scale, largest)
        dx[cols - 1] = 0.0
    s[:] = 0.0
    for c in range(channels):
        dx, dyc = a[c, k], dy[c, k]
        for j in range(cols):
            s[j] += dx[j] * dx[j] + dyc[j] * dyc[j]
    for j in range(cols):
        s[j] = log_weight(s[j], edge)
    for c in range(channels):
        dx, dyc, wx, wy = a[c, k], dy[c, k], px[c, k], py[c, k]
        for j in range(cols):
            wx[j] = dx[j] * s[j]
        for j in range(cols):
            wy[j] = dyc[j] * s[j]
    if not second:
        return
    for c in range(channels):
        xx, yy, xy, dyc = a[c, k], b[c, k], d[c, k], dy[c, k]
        for j in range(cols - 2, 0, -1):  # backwards: xx overwrites the dx it reads
            xx[j] = xx[j] - xx[j - 1]
        xx[0] = xx[cols - 1] = 0.0
        if 0 < r < rows - 1:
            above = dy[c, (r - 1) % 4]
            for j in range(cols):
                yy[j] = dyc[j] - above[j]
        else:
            yy[:] = 0.0
        for j in range(cols - 1):
            xy[j] = dyc[j + 1] - dyc[j]  # 0 on the last row, where dy is
        xy[cols - 1] = 0.0
    w[:] = 0.0
    for c in range(channels):
        xx, yy, xy = a[c, k], b[c, k], d[c, k]
        for j in range(cols):
            w[j] += xx[j] * xx[j] + yy[j] * yy[j] + (xy[j] + xy[j]) * xy[j]
    for j in range(cols):
        w[j] = second_order * log_weight(w[j], second_edge)
    for c in range(channels):
        xx, yy, xy = a[c, k], b[c, k], d[c, k]
        for j in range(cols):
            xx[j] *= w[j]
        for j in range(cols):
            yy[j] *= w[j]
        for j in range(cols):
            xy[j] *= w[j] + w[j]


@njit(cache=True, nogil=True, error_model="numpy")
def _vertical(x, r, scale, largest, dy):
    """``dy[c] = x[c, r + 1] - x[c, r]`` in units of the smoothing (0 on the last row)."""
    channels, rows, cols = x.shape
    for c in range(channels):
        here, below, out = x[c, r], x[c, min(r + 1, rows - 1)], dy[c]
        for j in range(cols):
            out[j] = scaled(below[j] - here[j], scale, largest)


@njit(cache=True, nogil=True)
def _divergence_row(i, rows, px, py, a, b, d, second, out):
    """Row ``i`` of the gradient of one channel into ``out``, from its rings of four rows (see
    :func:`_rows`)."""
    cols = out.shape[0]
    up, here, down = (i - 1) % 4, i % 4, (i + 1) % 4
    border = i == 0 or i == rows - 1
    for j in range(0, cols, 1 if border else max(cols - 1, 1)):
        out[j] = _pixel(i, j, rows, cols, up, here, down, px, py, a, b, d, second, False)
    if border:
        return
    # Inside, a loop the compiler vectorises (the flags are constants there).
    if second:
        for j in range(1, cols - 1):
            out[j] = _pixel(i, j, rows, cols, up, here, down, px, py, a, b, d, True, True)
    else:
        for j in range(1, cols - 1):
            out[j] = _pixel(i, j, rows, cols, up, here, down, px, py, a, b, d, False, True)


@njit(cache=True, nogil=True, inline="always")
def _pixel(i, j, rows, cols, up, here, down, px, py, a, b, d, second, inside):
    """Minus the divergence of the weighted gradient at pixel ``(i, j)``, then (``second``) the terms
    of the second differences whose stencils reach it, from the pixels ``(i - 1, j - 1)``,
    ``(i - 1, j)``, ``(i, j - 1)``, itself, ``(i, j + 1)``, ``(i + 1, j)`` in that order; ``up``,
    ``here``, ``down``: the ring rows of ``i - 1``, ``i``, ``i + 1``; ``inside``: ``(i, j)`` is not on
    the border."""
    g = np.float32(0.0)
    if inside or j + 1 < cols:
        g -= px[here, j]
    if inside or j > 0:
        g += px[here, j - 1]
    if inside or i + 1 < rows:
        g -= py[here, j]
    if inside or i > 0:
        g += py[up, j]
    if second:
        if inside or (i > 0 and j > 0):
            g += d[up, j - 1]
        if inside or i > 0:
            g += b[up, j] - d[up, j]
        if inside or j > 0:
            g += a[here, j - 1] - d[here, j - 1]
        middle = a[here, j] + b[here, j]
        g += d[here, j] - (middle + middle)
        if inside or j + 1 < cols:
            g += a[here, j + 1]
        if inside or i + 1 < rows:
            g += b[down, j]
    return g


@njit(cache=True, nogil=True)
def _to_unit_length(x, i, cols):
    """Vectors ``x[:, i, j]`` of the row ``i``, first ``cols`` columns, to unit length, in place
    (those shorter than :data:`_SHORTEST` left as they are)."""
    for j in range(cols):
        s = 0.0
        for k in range(x.shape[0]):
            s += x[k, i, j] * x[k, i, j]
        norm = np.sqrt(s)
        if norm > _SHORTEST:
            scale = 1.0 / max(norm, _SHORTEST)
            for k in range(x.shape[0]):
                x[k, i, j] *= scale


def iterate(
    q: list[np.ndarray],
    threshold: float,
    analysis: Callable[[np.ndarray], np.ndarray],
    synthesis: Callable[[np.ndarray], np.ndarray],
    unit_vectors: tuple[int, int] | None = None,
    folded: bool = False,
    second_across: bool = False,
) -> Iterator[np.ndarray]:
    """The restored channels, after 0, 1, 2, ... iterations (without end).

    Parameters
    ----------
    q : list of ndarray of int, shape (H, W) each
        Bin indices of every channel's coefficients, in the basis of the file.
    threshold : float
        ``T``.
    analysis, synthesis : callables
        The file's transform, ``(C, H, W)`` samples to ``(C, H, W)`` coefficients (the channels
        together: local frames mix them), and its inverse; both may overwrite their argument.
    unit_vectors : (h, w), optional
        The three channels are the components of unit vectors over their first ``h`` rows and
        ``w`` columns (a normal map coded with its z): each step also brings those vectors
        back to unit length before the projection into the bins (+0.2 to +0.4 dB on the
        fandisk normal map at 0.25 to 1 bpp, measured with the plain total variation).
    folded : bool
        The channels are an octahedral geometry image (the file's spherical extension, or a folded
        normal map): the penalty also takes the differences across its folds (:func:`penalty_gradient`).
    second_across : bool
        And the second differences across them (a folded normal map; :func:`penalty_gradient`).

    Yields
    ------
    ndarray, shape (C, H, W): the channels, float64 for the first one (plain dequantization,
    reconstruction at :data:`bandelets.format.quantizer.RECONSTRUCTION` of each bin, :func:`dequantize`),
    float32 for the others where that one's largest magnitude is at most :data:`SINGLE_UP_TO`
    ``T`` (float64 otherwise). Each array is overwritten by the next step (the buffers are
    reused): copy one to keep it.
    """
    x = np.ascontiguousarray(synthesis(np.array([dequantize(b, threshold) for b in q])))
    yield x
    if min(x.shape[1:]) < 2:  # no gradient to follow
        while True:
            yield x
    # Nesterov's momentum (as in FISTA): each step starts from the last estimate pushed further
    # along the last move. Same gain as plain steps in 40 to 50 % of the iterations.
    largest = float(np.max(np.abs(x)))
    single = largest <= SINGLE_UP_TO * threshold and 2.0**-64 <= threshold <= 2.0**64
    dtype = np.float32 if single else np.float64
    with np.errstate(under="ignore"):  # float32: what is below its range is 0
        x = x.astype(dtype)
    ahead, t = x.copy(), 1.0
    # Where each step writes (the three images swap roles): allocated once, not at every iteration.
    spare = np.empty_like(x)
    constants = (SMOOTHING * threshold, EDGE * threshold, SECOND_ORDER, SECOND_EDGE * threshold)
    unit = (0, 0) if unit_vectors is None else unit_vectors
    folds = _folds(folded, second_across)
    # The coefficients of a projection (float64; float32 images are copied into it): made once, not at
    # every projection.
    wide = None
    for k in count(1):
        t_next = (1.0 + np.sqrt(1.0 + 4.0 * t * t)) / 2.0
        weight = (t - 1.0) / t_next
        project = k % PROJECT_EVERY == 0
        # The step, and unless it projects, the momentum into x: one pass over the image.
        _in_halves(ahead, constants, STEP * threshold, spare, x, -1.0 if project else weight, *unit, folds)
        if project:
            if dtype == np.float64:  # the images' buffers swap roles: spare is not always the same one
                wide = spare
            elif wide is None:
                wide = np.empty(spare.shape)
            np.copyto(wide, spare)
            c = analysis(wide)  # may overwrite wide
            for channel, bins in zip(c, q, strict=True):
                clip_into_bins(channel, bins, threshold)
            with np.errstate(under="ignore"):
                np.copyto(spare, synthesis(c))
            _extrapolate(spare.reshape(-1), x.reshape(-1), x.dtype.type(weight))
        ahead, x, spare, t = x, spare, ahead, t_next
        yield x


@njit(cache=True, nogil=True)
def _extrapolate(new, x, weight):
    """``x = new + weight (new - x)``, in place in ``x`` (flat arrays), with the rounding of
    :func:`_rows`."""
    for i in range(x.shape[0]):
        x[i] = (new[i] - x[i]) * weight + new[i]
