"""The default effort's guess of the hard-surface choices of the highest effort (issue 37).

At :data:`bandelets.codec.variants.VARIANTS_FROM` the encoder codes a normal map twice, with the
defaults and with Haar along the bandelet directions and the directions forced
(:data:`bandelets.codec.variants.VARIANTS`), and keeps the better file: +1.18 dB BD-PSNR on the
shared vent decal, but -1.5 dB on the generated bevel map and -0.3 to -1.1 dB on the leather, the
cobblestones and the acacia door when forced on them (BENCHMARKS.md, "Hard-surface normal maps").
Below that effort the encoder codes once, and :func:`wants_haar_along_directions` tells it from
the samples, in a few milliseconds, whether the variant is the one to code.

What sets the vent decal apart from every other map of the benchmarks is long runs of equal
samples along one axis and not the other: louvre slats and bevels whose profile varies across
them and is constant along them (62 % of its pixels start or continue a run of 8 equal samples
along the rows, 36 % along the columns). The generated bevel and crease maps have as many runs
but in both axes alike (plates), organic and stone maps few (:data:`RUN` and the bounds below;
the table of the run fractions of every map is in BENCHMARKS.md).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..format.fields import DEFAULT_TRANSFORM_1D, DEFAULT_WAVELET, Kind
from .options import EncodeOptions
from .variants import VARIANTS, VARIANTS_FROM

__all__ = ["RUN", "run_fractions", "wants_haar_along_directions", "with_guess"]

#: The length of a run of equal samples that counts.
RUN = 8
#: The lines (rows, columns) measured: one in this many.
STRIDE = 4
#: A map is guessed hard-surface when the run fraction of one axis is at least this ...
MOST_RUNS = 0.4
#: ... and exceeds the other axis's by at least this.
ANISOTROPY = 0.15


def run_fractions(array: np.ndarray, run: int = RUN) -> tuple[float, float]:
    """The fractions of the windows of ``run`` pixels along the rows, then the columns, of
    ``array`` (H, W, C), whose first two channels are equal in all ``run`` pixels (measured on
    every :data:`STRIDE`-th row, then column). ``(0, 0)`` for an array of another shape: the checks
    of the image that follow refuse what a normal map cannot be."""
    values = np.asarray(array)
    if values.ndim != 3 or values.shape[-1] < 2:
        return 0.0, 0.0
    values = values[..., :2]
    fractions = []
    for rows in (True, False):
        # every STRIDE-th line along the axis: the fractions of a map's texture, a quarter of the time
        lines = values[::STRIDE] if rows else values[:, ::STRIDE]
        step = lines[:, 1:] == lines[:, :-1] if rows else lines[1:] == lines[:-1]
        equal = step[..., 0] & step[..., 1]
        equal = equal if rows else equal.T  # runs along the last axis
        if equal.shape[1] < run - 1 or equal.shape[0] == 0:
            fractions.append(0.0)
            continue
        # a window of run pixels is run - 1 equal steps: a difference of cumulative counts
        total = np.zeros((equal.shape[0], equal.shape[1] + 1), np.int32)
        np.cumsum(equal, axis=1, out=total[:, 1:])
        fractions.append(float(np.mean(total[:, run - 1 :] - total[:, : -(run - 1)] == run - 1)))
    return fractions[0], fractions[1]


def wants_haar_along_directions(array: np.ndarray) -> bool:
    """Whether the normal map ``array`` has the runs of the vent decal (module docstring)."""
    rows, columns = run_fractions(array)
    return max(rows, columns) >= MOST_RUNS and abs(rows - columns) >= ANISOTROPY


def with_guess(array: np.ndarray, options: EncodeOptions, tiled: bool) -> EncodeOptions:
    """``options`` with the highest effort's hard-surface variant where the map wants it.

    Only below :data:`~bandelets.codec.variants.VARIANTS_FROM` (which tries both) and where that
    effort would try it: a normal map in one piece, the default wavelet, bandelets, the 1D
    transform and the lifting left to the encoder.
    """
    if (
        options.effort >= VARIANTS_FROM
        or options.kind != Kind.NORMAL_MAP
        or options.wavelet != DEFAULT_WAVELET
        or options.transform != "bandelet"
        or options.transform_1d != DEFAULT_TRANSFORM_1D
        or options.lifting is not None
        or tiled
        or not wants_haar_along_directions(array)
    ):
        return options
    return replace(options, **VARIANTS[1])
