"""Step (8) of the paper: the Lagrangian of a square for each direction, and the best one.

For a square ``S`` and a direction ``d`` (or NULL), with ``b`` the coefficients of ``S`` in
that basis::

    L(S, d) = sum_k (b_k - Q_T(b_k))**2  +  lambda T**2 (R_G(d) + R_B(b))

with the paper's ``lambda = 3/28``. The paper prices ``R_B`` at about 7 bits per significant
coefficient; our context coder spends much less on the zeros of a sparse square than on
the zeros of a busy one, so that model would overvalue bandeletization (DESIGN.md). The
rate model used here (:func:`coefficient_bits`) follows what the coder pays:

* significance: for every group of coefficients the coder sees with the same statistics
  (one group for a wavelet square, one per 1D Haar scale for a bandelet square), the
  ideal adaptive code length of which ``k`` of the ``n`` are significant,
  ``log2 binomial(n, k)``, times a calibrated factor;
* each significant coefficient of bin index ``m``: a fixed cost (sign and first magnitude
  decisions) plus a cost per doubling of ``m``.

The constants in :data:`RATE_MODEL` were fitted against the real coder's output on the
generated test surfaces (``benchmarks/calibrate_rate.py`` refits them and
``tests/test_lagrangian.py`` checks that the model tracks the real bits).

The search itself (:func:`best_directions`) is compiled with numba and runs over all squares of
one width in parallel: per square, the reorderings of :func:`bandelets.transform.geometry.directions` are
gathered, transformed and priced. Widths with few directions (4 and 8) try them all; wider
squares follow the paper's progressive refinement (every 4th direction, or the neighbourhoods of
the directions their four half-size squares chose, then around the best and the predicted one),
which cost 0.04 dB BD-PSNR on the generated crease map for a 3.8x faster search.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from numba import njit, prange

from ..format.fields import DEFAULT_TRANSFORM_1D
from ..format.quantizer import bin_and_error
from ..transform.bandeletize import ORDER, alpert_matrices, multiwavelet
from ..transform.geometry import directions
from ..transform.quadtree import MAX_WIDTH

__all__ = [
    "LAMBDA",
    "RATE_MODEL",
    "GEOMETRY_PRICE",
    "square_features",
    "coefficient_bits",
    "geometry_bits",
    "best_directions",
]

#: Squares with more than REFINE_ABOVE directions search every REFINE_STRIDE-th one first,
#: then refine around the best and around the predicted one (the paper's progressive
#: refinement of d).
REFINE_ABOVE = 100
REFINE_STRIDE = 4

#: The paper's Lagrange multiplier (Le Pennec and Mallat 2004).
LAMBDA = 3.0 / 28.0

#: Rate model, in bits: [significance factor, cost per significant coefficient, cost per
#: doubling of its bin index] for wavelet squares then for bandelet squares, then the
#: geometry: [bits of a NULL leaf, bits of a direction flag]. The bandelet squares' cost per
#: significant coefficient went from 5.9 to 5.5 bits with their contexts of format version 10
#: (BENCHMARKS, "Contexts for the bandelet coefficients (format version 10)").
RATE_MODEL = np.array([0.26, 3.73, 0.89, 0.14, 5.5, 0.8, 0.3, 1.0])

#: The geometry (leaves, directions, and the splits of :func:`bandelets.transform.bandelets.best_trees`) is
#: charged this many times its modelled bits. The coded geometry costs 1.3 to 1.55 times the
#: model's leaf bits (crease, bumps and fandisk normal maps at 256, 0.25 to 2 bpp, splits not
#: counted), and a direction must also repay what the restoration would have recovered without
#: it: 2 gained +0.03 to +0.08 dB BD-PSNR on every normal map tried (1.5: +0.01 to +0.05; 3 lost
#: on the crease map what it gained on the bumps), see BENCHMARKS.
GEOMETRY_PRICE = 2.0


@njit(cache=True, nogil=True)
def _libm_table(size: int, log_gamma: bool) -> np.ndarray:
    """``lgamma(i)`` or ``log2(i)`` (0 at 0) for ``i < size``, by the compiled code's own libm:
    looking them up gives the very values calling them would (CPython's lgamma differs)."""
    out = np.zeros(size)
    for i in range(1, size):
        out[i] = math.lgamma(i) if log_gamma else math.log2(i)
    return out


# Tables for the squares' sizes: a call to lgamma costs about 60 ns, one per 1D scale.
_LGAMMA = _libm_table(MAX_WIDTH * MAX_WIDTH + 2, True)
_LOG2 = _libm_table(1024, False)


@njit(cache=True, nogil=True, inline="always")
def _lgamma(n: int) -> float:
    return _LGAMMA[n] if n < _LGAMMA.shape[0] else math.lgamma(n)


@njit(cache=True, nogil=True, inline="always")
def _log2_binomial(n: int, k: int) -> float:
    if k == 0 or k == n:
        return 0.0
    return (_lgamma(n + 1) - _lgamma(k + 1) - _lgamma(n - k + 1)) / math.log(2.0)


@njit(cache=True, nogil=True)
def square_features(values: np.ndarray, threshold: float, k: int) -> tuple[float, float, float, float]:
    """What the rate model of one square depends on, and its quantization error.

    Parameters
    ----------
    values : ndarray, shape (n,)
        A wavelet square raveled (``k = 0``) or the 1D coefficients of a bandelet square,
        coarse first.
    threshold : float
        ``T``.
    k : int
        0 for a wavelet square (one group), else the order of the 1D transform: its scales
        ``[0, k), [k, 2k), [2k, 4k), ...`` are the groups.

    Returns
    -------
    (sum over groups of log2 binomial(n_g, significant_g), number of significant
    coefficients, sum of log2 of their bin indices, squared quantization error)
    """
    significance = 0.0
    count = 0.0
    magnitude = 0.0
    distortion = 0.0
    start = 0
    n = values.shape[0]
    while start < n:
        stop = n if k == 0 else (k if start == 0 else 2 * start)
        significant = 0
        for i in range(start, stop):
            m, e = bin_and_error(values[i], threshold)
            distortion += e
            # Adding _LOG2[0] = 0.0 leaves the sum as it is: no jump on significance.
            significant += m > 0
            magnitude += _LOG2[m] if m < _LOG2.shape[0] else math.log2(m)
        significance += _log2_binomial(stop - start, significant)
        count += significant
        start = stop
    return significance, count, magnitude, distortion


@njit(cache=True, nogil=True)
def coefficient_bits(values: np.ndarray, threshold: float, k: int, model: np.ndarray) -> tuple[float, float]:
    """Quantization error and modelled bits of the coefficients of one square.

    See :func:`square_features` for the arguments; ``model`` is :data:`RATE_MODEL`.

    Returns
    -------
    (squared error, bits)
    """
    significance, count, magnitude, distortion = square_features(values, threshold, k)
    base = 3 if k > 0 else 0
    return distortion, model[base] * significance + model[base + 1] * count + model[base + 2] * magnitude


def geometry_bits(width: int, model: np.ndarray = RATE_MODEL) -> tuple[float, float]:
    """Bits the search charges for the geometry of a leaf of ``width``: (NULL, any direction),
    :data:`GEOMETRY_PRICE` times the model's."""
    n_dirs = directions(width)[1].shape[0]
    return GEOMETRY_PRICE * float(model[6]), GEOMETRY_PRICE * float(model[7] + math.log2(n_dirs))


@njit(cache=True, nogil=True, inline="always")
def _offset_bits(offset: int) -> float:
    """Bits of a direction coded as an offset from the predicted one (see treecoding)."""
    if offset == 0:
        return 1.0
    return 3.0 + 2.0 * math.floor(math.log2(offset))


@njit(cache=True, nogil=True)
def _best_of_square(
    squares,
    samples,
    tmp,
    signal,
    orders,
    mats,
    threshold,
    model,
    null_bits,
    direction_bits,
    guess,
    allow_directions,
    stride,
    hints,
    n_hints,
) -> tuple[float, int]:
    """Best Lagrangian and direction (-1: NULL) of one square, its channels raveled in
    ``squares`` (C, n); ``samples``, ``tmp``, ``signal``: scratch of n. See :func:`best_directions`."""
    channels, n = squares.shape
    n_dirs = orders.shape[0]
    order_1d = mats.shape[1] // 2
    price = LAMBDA * threshold * threshold
    best_cost = price * null_bits
    best = -1
    for k in range(channels):
        distortion, bits = coefficient_bits(squares[k], threshold, 0, model)
        best_cost += distortion + price * bits
    # A square whose energy is at most T**2 in every channel quantizes to zero in every
    # basis (no coefficient can exceed T): its directions cannot beat NULL.
    quiet = True
    for k in range(channels):
        energy = 0.0
        for i in range(n):
            energy += squares[k, i] * squares[k, i]
        if energy > threshold * threshold:
            quiet = False
    if not allow_directions or quiet:
        return best_cost, best
    has_hints = False
    if stride > 1:
        for h in range(n_hints):
            has_hints = has_hints or hints[h] >= 0
    # A large square none of whose half-size squares found a direction is unlikely to
    # have one: it is scanned four times more coarsely.
    scan = 4 * stride if stride > 1 and n_hints > 0 and not has_hints else stride
    # Progressive refinement: the directions near the hints (the best directions of
    # the four half-size squares inside) or, without hints, every stride-th
    # direction; then the neighbours of the best so far and of the predicted one.
    for step in range(n_hints + 3):
        if step < n_hints:
            centre = hints[step]
            if not has_hints or centre < 0:
                continue
            first, last, every = centre - stride + 1, centre + stride - 1, 1
        elif step == n_hints:
            if has_hints:
                continue
            first, last, every = 0, n_dirs - 1, scan
        else:
            centre = best if step == n_hints + 1 else guess
            if stride == 1 or centre < 0:
                continue
            radius = scan if step == n_hints + 1 else stride
            first, last, every = centre - radius + 1, centre + radius - 1, 1
        for dd in range(first, last + 1, every):
            d = dd % n_dirs
            if guess < 0:
                candidate = price * direction_bits
            else:
                offset = abs((d - guess + n_dirs // 2) % n_dirs - n_dirs // 2)
                candidate = price * GEOMETRY_PRICE * (model[7] + _offset_bits(offset))
            for k in range(channels):
                for i in range(n):
                    samples[i] = squares[k, orders[d, i]]
                multiwavelet(samples, tmp, signal, mats)
                distortion, bits = coefficient_bits(signal, threshold, order_1d, model)
                candidate += distortion + price * bits
                if candidate >= best_cost:
                    break
            if candidate < best_cost:
                best_cost = candidate
                best = d
    return best_cost, best


#: The squares of one call are searched in this many runs, each with its own scratch arrays
#: (allocations per square cost as much as the search of a 4 x 4 square).
_RUNS = 64

#: Calls with less work than this (squares x samples x directions scanned) run on one thread.
#: On the shared 2-core machine under load a parallel launch waited about 7 ms for the other
#: core, more than the whole of most calls (0.06 to 5 ms at 512 x 512: 512 x 512 x 3 at 1 bpp
#: took 1.36 s with every call parallel, 1.01 s with none); lightly loaded, every call parallel
#: took 0.86 to 0.90 s, this threshold (18 of the 33 calls of each try of rate control) 0.87 to 0.93 s.
PARALLEL_WORK = 2**20


@njit(cache=True, nogil=True)
def _search_run(
    run,
    runs,
    cost,
    best,
    subbands,
    width,
    orders,
    mats,
    threshold,
    model,
    null_bits,
    direction_bits,
    predicted,
    allow_directions,
    stride,
    hints,
    visit,
) -> None:
    """The squares of run ``run`` of ``runs`` (runs of ``visit``), into ``cost`` and ``best``."""
    channels = subbands.shape[0]
    cols = cost.shape[1]
    total = cost.size
    n = width * width
    squares = np.empty((channels, n))
    samples = np.empty(n)
    tmp = np.empty(n)
    signal = np.empty(n)
    for s in range(run * total // runs, (run + 1) * total // runs):
        r = visit[s] // cols
        c = visit[s] % cols
        for k in range(channels):
            for i in range(width):
                for j in range(width):
                    squares[k, i * width + j] = subbands[k, r * width + i, c * width + j]
        cost[r, c], best[r, c] = _best_of_square(
            squares,
            samples,
            tmp,
            signal,
            orders,
            mats,
            threshold,
            model,
            null_bits,
            direction_bits,
            predicted[r, c],
            allow_directions,
            stride,
            hints[r, c],
            hints.shape[2],
        )


@njit(cache=True, nogil=True, parallel=True)
def _search_parallel(
    runs,
    cost,
    best,
    subbands,
    width,
    orders,
    mats,
    threshold,
    model,
    null_bits,
    direction_bits,
    predicted,
    allow_directions,
    stride,
    hints,
    visit,
) -> None:
    for run in prange(runs):
        _search_run(
            run,
            runs,
            cost,
            best,
            subbands,
            width,
            orders,
            mats,
            threshold,
            model,
            null_bits,
            direction_bits,
            predicted,
            allow_directions,
            stride,
            hints,
            visit,
        )


@njit(cache=True, nogil=True)
def _search_serial(
    runs,
    cost,
    best,
    subbands,
    width,
    orders,
    mats,
    threshold,
    model,
    null_bits,
    direction_bits,
    predicted,
    allow_directions,
    stride,
    hints,
    visit,
) -> None:
    for run in range(runs):
        _search_run(
            run,
            runs,
            cost,
            best,
            subbands,
            width,
            orders,
            mats,
            threshold,
            model,
            null_bits,
            direction_bits,
            predicted,
            allow_directions,
            stride,
            hints,
            visit,
        )


def best_directions(
    subbands: np.ndarray,
    width: int,
    threshold: float,
    *,
    allow_directions: bool = True,
    transform_1d: str = DEFAULT_TRANSFORM_1D,
    predicted: np.ndarray | None = None,
    hints: np.ndarray | None = None,
    model: np.ndarray = RATE_MODEL,
) -> tuple[np.ndarray, np.ndarray]:
    """Best Lagrangian and direction of every square of ``width`` tiling ``subbands``.

    The channels of an image share their geometry (a crease is at the same place in the
    three components of a normal map), so the Lagrangian of a square for a direction is
    summed over the channels.

    Parameters
    ----------
    subbands : ndarray, shape (C, h, w), float64
        The same subband of each channel; only the top-left
        ``floor(h/width)*width x floor(w/width)*width`` region is tiled.
    width : int
        Square width ``L``, a power of two >= 4.
    threshold : float
        ``T``.
    allow_directions : bool
        False prices NULL only (the wavelet baseline).
    transform_1d : str
        One of :data:`bandelets.format.header.TRANSFORMS_1D`.
    predicted : ndarray of int, shape (h // width, w // width), optional
        Direction each square's geometry coder will predict (-1: none); directions near it
        are priced at what coding them as an offset costs.
    hints : ndarray of int, shape (h // width, w // width, n), optional
        Directions (indices at this width, -1: none) worth searching around first, for
        instance those chosen for the four half-size squares inside. For widths with many
        directions a square with hints searches only around them.

    Returns
    -------
    cost : ndarray, shape (h // width, w // width)
        ``min_d L(S, d)``.
    direction : ndarray of int64, same shape
        The minimising direction index, -1 for NULL.
    """
    null_bits, direction_bits = geometry_bits(width, model)
    shape = (subbands.shape[1] // width, subbands.shape[2] // width)
    if predicted is None:
        predicted = np.full(shape, -1, np.int64)
    if hints is None:
        hints = np.full(shape + (0,), -1, np.int64)
    orders = directions(width)[1]
    stride = REFINE_STRIDE if orders.shape[0] > REFINE_ABOVE else 1
    cost = np.empty(shape)
    best = np.full(shape, -1, np.int64)
    total = shape[0] * shape[1]
    work = total * width * width * (-(-orders.shape[0] // stride) if allow_directions else 1)
    search = _search_parallel if work >= PARALLEL_WORK else _search_serial
    search(
        min(_RUNS, total),
        cost,
        best,
        np.ascontiguousarray(subbands, dtype=np.float64),
        width,
        orders,
        alpert_matrices(width * width, ORDER[transform_1d]),
        float(threshold),
        model,
        null_bits,
        direction_bits,
        np.ascontiguousarray(predicted, dtype=np.int64),
        allow_directions,
        stride,
        np.ascontiguousarray(hints, dtype=np.int64),
        _visit_order(total),
    )
    return cost, best


@cache
def _visit_order(n: int) -> np.ndarray:
    """A fixed shuffle of the ``n`` squares: the threads of the parallel loop take contiguous
    runs of it, which then hold as many busy squares each (the creases of an image are not
    spread evenly over its rows). The result does not depend on it."""
    out = np.random.default_rng(0).permutation(n)
    out.flags.writeable = False
    return out
