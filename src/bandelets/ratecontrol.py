"""Rate control: the threshold ``T`` that meets a target file size or a target PSNR.

The encoder at a given ``T`` is a black box here (``encode_at(T)`` returns the file); the
file size falls and the error grows as ``T`` grows, up to small non-monotone wiggles of the
basis choice. Both searches bracket ``T`` by factors of 4, then bisect on ``log T``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from tqdm import tqdm

__all__ = ["for_size", "for_quality", "SIZE_TOLERANCE"]

#: A size-targeted file lands in ``[(1 - SIZE_TOLERANCE) * target, target]`` bytes.
SIZE_TOLERANCE = 0.03
_MAX_STEPS = 48


def for_size(encode_at: Callable[[float], bytes], target_bytes: int, t_max: float,
             progress: bool = False):
    """Largest file of at most ``target_bytes`` bytes, found by bisection on ``T``.

    Parameters
    ----------
    encode_at : callable
        ``T -> result`` where ``result.data`` is the file.
    target_bytes : int
    t_max : float
        A threshold above every coefficient (the smallest possible file).
    progress : bool
        Show a progress bar (on a terminal only).

    Returns
    -------
    The ``encode_at`` result kept; it is within ``SIZE_TOLERANCE`` below the target unless
    even the smallest threshold tried (``1e-7 t_max``) gives a smaller file.

    Raises
    ------
    ValueError
        When even the smallest possible file is larger than the target.
    """
    with tqdm(total=_MAX_STEPS, desc="rate control", unit="encode", disable=not progress, leave=False) as bar:

        def run(t):
            bar.update()
            return encode_at(t)

        smallest = run(t_max)
        if len(smallest.data) > target_bytes:
            raise ValueError(
                f"target of {target_bytes} bytes cannot be reached: the smallest file is "
                f"{len(smallest.data)} bytes"
            )
        low_fits = (1 - SIZE_TOLERANCE) * target_bytes
        best, t_hi = smallest, t_max  # t_hi: known to fit
        t_lo = t_max
        while True:  # bracket: find a T whose file is too large
            t_lo /= 4
            result = run(t_lo)
            if len(result.data) > target_bytes:
                break
            best, t_hi = result, t_lo
            if len(result.data) >= low_fits or t_lo < 1e-7 * t_max:
                return best
        for _ in range(_MAX_STEPS):
            t = float(np.sqrt(t_lo * t_hi))
            result = run(t)
            if len(result.data) > target_bytes:
                t_lo = t
            else:
                if len(result.data) > len(best.data):
                    best = result
                t_hi = t
            if len(best.data) >= low_fits or t_hi / t_lo < 1 + 1e-6:
                break
        return best


def for_quality(encode_at: Callable[[float], bytes], quality: Callable[[bytes], float],
                target: float, t_max: float, progress: bool = False):
    """Smallest file whose ``quality(file) >= target`` (a PSNR), by bisection on ``T``.

    Stops when the kept file is within 0.05 dB of the target or ``T`` is pinned to 0.5 %.

    Raises
    ------
    ValueError
        When even ``1e-7 t_max`` does not reach the target.
    """
    with tqdm(total=_MAX_STEPS, desc="rate control", unit="encode", disable=not progress, leave=False) as bar:

        def run(t):
            bar.update()
            result = encode_at(t)
            return result, quality(result.data)

        t_hi = t_max
        t_lo = t_max
        while True:
            t_lo /= 4
            result, q = run(t_lo)
            if q >= target:
                best = result
                break
            t_hi = t_lo
            if t_lo < 1e-7 * t_max:
                raise ValueError(f"target PSNR of {target:g} dB cannot be reached (best {q:.2f} dB)")
        if t_hi == t_max:
            result, q = run(t_max)
            if q >= target:
                return result
        for _ in range(_MAX_STEPS):
            t = float(np.sqrt(t_lo * t_hi))
            result, q = run(t)
            if q >= target:
                best, t_lo = result, t
                if q - target < 0.05:
                    break
            else:
                t_hi = t
            if t_hi / t_lo < 1.005:
                break
        return best
