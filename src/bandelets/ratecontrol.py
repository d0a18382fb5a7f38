"""Rate control: the threshold ``T`` that meets a target file size or a target PSNR.

The encoder at a given ``T`` is a black box here (``encode_at(T)`` returns a result whose
``data`` is the file). File size falls and error grows with ``T``, close to power laws, up to
small non-monotone wiggles of the basis choice. Both searches therefore step by the secant
of ``log size`` (or PSNR) against ``log T``, inside a bracket that shrinks at every step, and
fall back to bisection of ``log T`` when the secant leaves the bracket: a target is usually
met in three to five encodings.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from tqdm import tqdm

__all__ = ["for_size", "for_quality", "SIZE_TOLERANCE"]

#: A size-targeted file lands in ``[(1 - SIZE_TOLERANCE) * target, target]`` bytes.
SIZE_TOLERANCE = 0.03
_MAX_STEPS = 40
_SMALLEST = 1e-7  # relative to t_max: below this, the file cannot grow meaningfully


def _next(x_low: float | None, x_high: float | None, secant: float) -> float:
    """Secant step, kept strictly inside the bracket ``(x_low, x_high)`` of log T."""
    if x_low is not None and x_high is not None:
        margin = 0.1 * (x_high - x_low)
        if not x_low + margin <= secant <= x_high - margin:
            return 0.5 * (x_low + x_high)
    return secant


def _search(measure, goal: float, x0: float, x_min: float, x_max: float, slope0: float, bar) -> None:
    """Drive ``measure(x) -> (value, done, below)`` towards ``goal`` in ``x = log T``.

    ``below`` says the target lies at larger ``x``. Returns when ``done``, when the bracket
    has shrunk to nothing, or after ``_MAX_STEPS`` measures.
    """
    x, x_low, x_high = x0, None, None
    last = None
    for _ in range(_MAX_STEPS):
        x = min(max(x, x_min), x_max)
        value, done, below = measure(x)
        bar.update()
        if done:
            return
        if below:
            x_low = x if x_low is None else max(x_low, x)
        else:
            x_high = x if x_high is None else min(x_high, x)
        slope = slope0
        if last is not None and last[0] != x and last[1] != value:
            slope = (value - last[1]) / (x - last[0])
            if slope * slope0 <= 0:  # a wiggle: trust the typical slope instead
                slope = slope0
        last = (x, value)
        x = _next(x_low, x_high, x + (goal - value) / slope)
        if x_low is not None and x_high is not None and x_high - x_low < 1e-4:
            return


def for_size(encode_at: Callable, target_bytes: int, t_max: float, t_guess: float, progress: bool = False):
    """Largest file of at most ``target_bytes`` bytes, by a secant search on ``log T``.

    Parameters
    ----------
    encode_at : callable
        ``T -> result`` with ``result.data`` the file.
    target_bytes : int
    t_max : float
        A threshold above every coefficient (gives the smallest possible file).
    t_guess : float
        Where to start.
    progress : bool
        Progress bar (on a terminal only).

    Returns
    -------
    The ``encode_at`` result kept: within ``SIZE_TOLERANCE`` below the target, unless even
    ``1e-7 t_max`` gives a smaller file (then that one).

    Raises
    ------
    ValueError
        When even the smallest possible file is larger than the target.
    """
    best = None
    floor = math.log(_SMALLEST * t_max)
    goal = math.log((1 - SIZE_TOLERANCE / 2) * target_bytes)

    def measure(x):
        nonlocal best
        result = encode_at(math.exp(x))
        size = len(result.data)
        if size <= target_bytes and (best is None or size > len(best.data)):
            best = result
        if size > target_bytes and x >= math.log(t_max):
            raise ValueError(
                f"target of {target_bytes} bytes cannot be reached: the smallest file is {size} bytes"
            )
        done = (1 - SIZE_TOLERANCE) * target_bytes <= size <= target_bytes or (
            size < target_bytes and x <= floor
        )
        return math.log(size), done, size > target_bytes

    with tqdm(desc="rate control", unit="encode", disable=not progress, leave=False) as bar:
        _search(measure, goal, math.log(t_guess), floor, math.log(t_max), -0.6, bar)
        if best is None:  # the search wandered: the smallest file is the answer, if it fits
            measure(math.log(t_max))
    return best


def for_quality(
    encode_at: Callable,
    quality: Callable[[bytes], float],
    target: float,
    t_max: float,
    t_guess: float,
    progress: bool = False,
):
    """Smallest file whose ``quality(file) >= target`` (a PSNR in dB), by a secant search.

    Stops when the kept file is within 0.05 dB above the target or ``T`` is pinned.

    Raises
    ------
    ValueError
        When even ``1e-7 t_max`` does not reach the target.
    """
    best = None
    floor = math.log(_SMALLEST * t_max)

    def measure(x):
        nonlocal best
        result = encode_at(math.exp(x))
        q = quality(result.data)
        if q >= target and (best is None or len(result.data) < len(best.data)):
            best = result
        if q < target and x <= floor:
            raise ValueError(f"target PSNR of {target:g} dB cannot be reached (best {q:.2f} dB)")
        return q, target <= q < target + 0.05, q >= target

    with tqdm(desc="rate control", unit="encode", disable=not progress, leave=False) as bar:
        # PSNR falls by about 20 log10(e) = 8.7 dB per unit of log T.
        _search(measure, target + 0.025, math.log(t_guess), floor, math.log(t_max), -8.7, bar)
    if best is None:
        raise ValueError(f"target PSNR of {target:g} dB could not be met")
    return best
