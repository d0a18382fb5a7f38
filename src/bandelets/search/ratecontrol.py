"""Rate control: the threshold ``T`` that meets a target file size or a target PSNR.

The encoder at a given ``T`` is a black box here (``encode_at(T)`` returns a result whose
``data`` is the file). File size falls and error grows with ``T``, close to power laws, up to
small non-monotone wiggles of the basis choice. Both searches therefore step by the secant
of ``log size`` (or PSNR) against ``log T``, inside a bracket that shrinks at every step, and
fall back to bisection of ``log T`` when the secant leaves the bracket. The size search
follows a model of the size computed from the wavelet coefficients (:func:`size_model`)
and only corrects its offset by the secant: a target size is usually met in one or two
encodings (a plain secant on the size needed four at 2048 x 2048 x 3, 1 bpp).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..runtime.progress import Progress

__all__ = ["for_size", "for_quality", "size_model", "SIZE_TOLERANCE", "SIZE_MODEL"]

#: A size-targeted file lands in ``[(1 - SIZE_TOLERANCE) * target, target]`` bytes.
SIZE_TOLERANCE = 0.03
_MAX_STEPS = 40
_SMALLEST = 1e-7  # relative to t_max: below this, the file cannot grow meaningfully
#: Coded bits per coefficient ``exp(a) p**b`` from the proxy's ``p`` (see :func:`size_model`),
#: fitted by least squares on 16 encodings of the crease map.
SIZE_MODEL = (-0.29, 1.17)


def _next(x_low: float | None, x_high: float | None, secant: float) -> float:
    """Secant step, kept strictly inside the bracket ``(x_low, x_high)`` of log T: bisection
    when it leaves the bracket, else at least 2 % of the bracket away from its ends (a
    near miss of the target is often followed by a step just beside it)."""
    if x_low is not None and x_high is not None:
        if not x_low < secant < x_high:
            return 0.5 * (x_low + x_high)
        margin = 0.02 * (x_high - x_low)
        return min(max(secant, x_low + margin), x_high - margin)
    return secant


def _solve(f: Callable[[float], float], x_min: float, x_max: float) -> float:
    """A root of ``f``, positive at ``x_min`` and negative at ``x_max`` (else that end), by bisection."""
    if f(x_min) <= 0:
        return x_min
    if f(x_max) >= 0:
        return x_max
    for _ in range(60):
        middle = 0.5 * (x_min + x_max)
        if f(middle) > 0:
            x_min = middle
        else:
            x_max = middle
    return 0.5 * (x_min + x_max)


def _search(measure, goal: float, x0: float, x_min: float, x_max: float, model, drift: float) -> None:
    """Drive ``measure(x) -> (value, done, below)`` towards ``goal`` in ``x = log T``.

    ``below`` says the target lies at larger ``x``. ``model(x)``, decreasing, predicts the value
    up to an offset that changes slowly with ``x`` (by ``drift`` per unit, until two measures
    give its secant): each step solves model plus offset = goal. Returns when ``done``, when
    the bracket has shrunk to nothing, or after ``_MAX_STEPS`` measures.
    """
    x, x_low, x_high = x0, None, None
    last = None
    for _ in range(_MAX_STEPS):
        x = min(max(x, x_min), x_max)
        value, done, below = measure(x)
        if done:
            return
        if below:
            x_low = x if x_low is None else max(x_low, x)
        else:
            x_high = x if x_high is None else min(x_high, x)
        offset = value - model(x)
        slope, low, high = drift, x_min, x_max
        # A rising secant is a wiggle of the basis choice: trust the prior drift instead.
        if last is not None and last[0] != x and (value - last[1]) / (x - last[0]) < 0:
            slope = (offset - last[2]) / (x - last[0])
            # The secant of the offset holds near ``x``, not across the whole range (where it can
            # outgrow the model's own slope and send the search to an end): a step of at most 1.
            low, high = max(x_min, x - 1.0), min(x_max, x + 1.0)
        last = (x, value, offset)

        def error(y: float, at: float = x, offset: float = offset, slope: float = slope) -> float:
            return model(y) + offset + slope * (y - at) - goal

        x = _next(x_low, x_high, _solve(error, low, high))
        if x_low is not None and x_high is not None and x_high - x_low < 1e-4:
            return


def size_model(magnitudes: np.ndarray, count: int | None = None) -> Callable[[float], float]:
    """A model of the log file size (bytes) against ``x = log T``, from the coefficients.

    With ``k`` of the ``N`` coefficients above ``T``, ``P = N h(k / N) + 2 k + sum log2(|c| / T)``
    bits (which are significant, a sign and a first magnitude decision each, then their bin
    indices) is a proxy of the coded size; the coder spends ``exp(SIZE_MODEL[0]) (P / N) **
    SIZE_MODEL[1]`` bits per coefficient on the generated crease maps of 256 to 2048 pixels a
    side at 0.15 to 4 bpp (within 8 %). Rate control needs it to be right locally: the
    offset it finds at one threshold holds at the next.

    Parameters
    ----------
    magnitudes : ndarray, shape (N,)
        Absolute values of all coefficients, any order, or of a regular sample of them.
    count : int, optional
        How many coefficients there are, when ``magnitudes`` is a sample (the tiles of a large
        image, :mod:`bandelets.codec.tiles`).

    Returns
    -------
    callable ``x -> log(bytes)``, decreasing.
    """
    magnitudes = np.asarray(magnitudes, np.float64).ravel()
    n = magnitudes.size if count is None else count
    # A model needs no more than a regular sample of a million (an odd step: no aliasing
    # with the power-of-two layout of the subbands).
    ordered = np.sort(magnitudes[:: max(1, magnitudes.size // 2**20) | 1])
    scale = n / ordered.size
    logs = np.concatenate([[0.0], np.cumsum(np.log2(np.maximum(ordered, 1e-300)))])
    alpha, beta = SIZE_MODEL

    def model(x: float) -> float:
        above = ordered.size - int(np.searchsorted(ordered, math.exp(x), side="right"))
        significant = scale * above
        p = min(significant / n, 1.0)
        choice = 0.0 if p in (0.0, 1.0) else -n * (p * math.log2(p) + (1 - p) * math.log2(1 - p))
        levels = scale * (logs[-1] - logs[ordered.size - above]) - significant * x / math.log(2.0)
        proxy = max(choice + 2.0 * significant + levels, 1.0) / n
        return math.log(n / 8) + alpha + beta * math.log(proxy)

    return model


def first_threshold(target_bytes: int, t_max: float, model: Callable) -> float:
    """The ``T`` where :func:`for_size` starts its search: where ``model`` meets the target."""
    goal = math.log((1 - SIZE_TOLERANCE / 2) * target_bytes)
    return math.exp(_solve(lambda x: model(x) - goal, math.log(_SMALLEST * t_max), math.log(t_max)))


def for_size(
    encode_at: Callable,
    target_bytes: int,
    t_max: float,
    model: Callable,
    progress: Progress | None = None,
    t_min: float = 0.0,
    room: int = 0,
    probe: Callable[[float], float] | None = None,
):
    """Largest file of at most ``target_bytes - room`` bytes, by a model-guided secant search on
    ``log T``.

    Parameters
    ----------
    encode_at : callable
        ``T -> result`` with ``result.data`` the file.
    target_bytes : int
    t_max : float
        A threshold above every coefficient (gives the smallest possible file).
    model : callable
        ``log T -> log(bytes)`` up to a slowly changing offset (:func:`size_model`): the
        search starts where it meets the target and steps by it.
    progress : Progress, optional
        Counts the encodings (:class:`bandelets.runtime.progress.Progress`).
    t_min : float
        The smallest threshold to try (at most ``t_max``).
    room : int
        Bytes to leave free below the target (the loop filter's, :mod:`bandelets.restore.loopfilter`),
        at most ``SIZE_TOLERANCE / 2`` of it: the file lands in ``[(1 - SIZE_TOLERANCE) target,
        target - room]``, within the tolerance whether or not the room is taken.
    probe : callable, optional
        ``T -> bytes``: a prediction of the file's size at ``T``, much cheaper than ``encode_at``
        and off by a factor that holds over the thresholds near the target (the encoder's
        wavelet file). Where given, the model's offset is measured by the probe at the model's
        first threshold, and the first file is encoded where model and offset meet the target:
        often within the tolerance already. The file kept is always one ``encode_at`` made.

    Returns
    -------
    The ``encode_at`` result kept: within ``SIZE_TOLERANCE`` below the target, unless even
    ``max(1e-7 t_max, t_min)`` gives a smaller file (then that one).

    Raises
    ------
    ValueError
        When even the smallest possible file is larger than the target.
    """
    best = None
    floor = math.log(max(_SMALLEST * t_max, t_min))
    room = min(max(int(room), 0), int(SIZE_TOLERANCE / 2 * target_bytes))
    goal = math.log((1 - SIZE_TOLERANCE / 2) * target_bytes - room / 2)
    largest = target_bytes - room

    def measure(x):
        nonlocal best
        result = encode_at(math.exp(x))
        size = len(result.data)
        if progress is not None:
            progress.step(f"T={math.exp(x):.3g}: {size} bytes")
        if size <= largest and (best is None or size > len(best.data)):
            best = result
        if size > largest and x >= math.log(t_max):
            raise ValueError(
                f"target of {target_bytes} bytes cannot be reached: the smallest file is {size} bytes"
            )
        done = (1 - SIZE_TOLERANCE) * target_bytes <= size <= largest or (size < largest and x <= floor)
        return math.log(size), done, size > largest

    start = math.log(first_threshold(target_bytes - room, t_max, model))
    if probe is not None:
        # Aimed at the upper part of the tolerance: a larger file is a better one.
        aim = math.log((1 - SIZE_TOLERANCE / 3) * target_bytes - room)
        offset = math.log(max(probe(math.exp(start)), 1.0)) - model(start)
        start = _solve(lambda x: model(x) + offset - aim, floor, math.log(t_max))
    _search(measure, goal, start, floor, math.log(t_max), model, 0.0)
    if best is None:  # the search wandered: the smallest file is the answer, if it fits
        measure(math.log(t_max))
    return best


def for_quality(
    encode_at: Callable,
    quality: Callable[[Any], float],
    target: float,
    t_max: float,
    t_guess: float,
    progress: Progress | None = None,
    label: Callable[[float], str] = lambda q: f"PSNR of {q:.2f} dB",
    t_min: float = 0.0,
):
    """Smallest file whose ``quality(file) >= target`` (a PSNR in dB), by a secant search.

    ``encode_at(T)`` returns an encoded file (with its bytes in ``.data``), which ``quality``
    is given whole: the encoder may already know the file's PSNR. Any other quality that,
    like a PSNR, falls by about 8.7 per unit of ``log T`` works as well (``-20 log10`` of an
    error proportional to ``T``); ``label`` names a value of it in error messages.

    Stops when the kept file is within 0.05 dB above the target, when a file comes back that
    was met before (a plateau: the smallest file meets the target, or the quality jumps over it
    between two files), when ``t_max`` (the smallest file) meets it, or when ``T`` is pinned.

    Raises
    ------
    ValueError
        When even ``max(1e-7 t_max, t_min)`` does not reach the target.
    """
    best = None
    floor = math.log(max(_SMALLEST * t_max, t_min))
    seen = set()

    def measure(x):
        nonlocal best
        result = encode_at(math.exp(x))
        q = quality(result)
        if progress is not None:
            progress.step(f"T={math.exp(x):.3g}: {label(q)}, {len(result.data)} bytes")
        if q >= target and (best is None or len(result.data) < len(best.data)):
            best = result
        if q < target and x <= floor:
            raise ValueError(f"target {label(target)} cannot be reached (best {label(q)})")
        # A file met before (same size and quality; its header differs by T): the search is on a
        # plateau (the smallest file, or a step between two files) where no threshold gives more.
        again = (len(result.data), q) in seen
        seen.add((len(result.data), q))
        done = target <= q < target + 0.05 or (again and best is not None)
        done = done or (q >= target and x >= math.log(t_max))
        return min(q, target + 100.0), done, q >= target  # an exact file (inf dB) steers as a good one

    # PSNR falls by about 20 log10(e) = 8.7 dB per unit of log T.
    x0, x_max = math.log(t_guess), math.log(t_max)
    _search(measure, target + 0.025, x0, floor, x_max, lambda x: -8.7 * x, 0.0)
    if best is None:
        raise ValueError(f"target {label(target)} could not be met")
    return best
