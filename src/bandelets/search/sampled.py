"""The lifting's choices on a large image made on a sample of it: which directions' variant (the
slopes alone, the pair codes, one level deeper) and whether the directions pay are decided on a
mosaic of crops, then the whole image is lifted once with the variant chosen.

:func:`bandelets.search.directions.lift` decides by the estimated cost of whole files: on a 2048 x
2048 map it makes three analyses and three to five costs (each a synthesis and a quantization of
the whole image), a quarter of the CPU time of a 1 bpp encode. Those are sums over the image of
what its blocks cost, which a regular sample of its crops estimates; the directions of each block
are then chosen on the whole image as before (:func:`bandelets.search.directions.chosen_analysis`),
only the variant comes from the sample. Applied from :data:`SAMPLED_ABOVE` pixels: above the size
where a rate target would try the alternative whose estimate is close
(:data:`bandelets.codec.alternatives.TRIAL_PIXELS`), so no trial is lost to it.
"""

from __future__ import annotations

import numpy as np

from ..transform.directional import SLOPES_97
from . import directions

__all__ = ["CROP", "SAMPLED_ABOVE", "SHARE", "applies", "lifted", "mosaic"]

#: Images of more pixels than this decide the lifting's variant on a mosaic (:func:`lifted`).
SAMPLED_ABOVE = 1024 * 1024
#: About this share of the image is in the mosaic.
SHARE = 0.125
#: Side of the crops of the mosaic (or ``2**levels``, if larger: the crops keep the transform's blocks).
CROP = 256


def applies(shape: tuple[int, int]) -> bool:
    """Whether the lifting of an image of ``shape`` (rows, columns) is decided on a mosaic."""
    return shape[0] * shape[1] > SAMPLED_ABOVE


def mosaic(channels: list[np.ndarray], levels: int, share: float = SHARE) -> list[np.ndarray]:
    """A regular sample of the (padded) ``channels``: crops of :data:`CROP` (at least ``2**levels``)
    a side, about ``share`` of them, taken along diagonals (every row and every column of crops is
    sampled) and laid side by side, row of crops by row of crops; the channels themselves where a
    side is shorter than a crop."""
    side = max(CROP, 1 << levels)
    rows, cols = channels[0].shape[0] // side, channels[0].shape[1] // side
    if not rows or not cols:  # a strip narrower than a crop: the channels themselves
        return list(channels)
    step = max(1, round(1 / share))
    per_row = max(1, cols // step)
    # A narrow image (fewer columns of crops than ``step``): not every row of crops either.
    every = max(1, round(step * per_row / cols))
    cells = [[(r, (r + j * step) % cols) for j in range(per_row)] for r in range(0, rows, every)]
    return [
        np.block([[x[r * side : (r + 1) * side, c * side : (c + 1) * side] for r, c in row] for row in cells])
        for x in channels
    ]


def lifted(
    channels: list[np.ndarray],
    plain: list,
    levels: int,
    lifting: int,
    threshold: float,
    check: bool,
    frames: bool,
) -> tuple[list, list | None, int, None]:
    """:func:`bandelets.codec.alternatives.lifted` of the padded ``channels`` with its choices made on
    their :func:`mosaic`: the variant of :func:`bandelets.search.directions.lift` (the levels lifted,
    whether the pair codes may be chosen) and, with ``check``, whether the directions pay
    (:func:`bandelets.search.directions.pays`; ``frames``: a normal map in local frames). Returns
    the coefficients, the directions (None: the ``plain`` ones, not lifted), the levels lifted and
    None (no trial: these sizes are not tried both ways)."""
    sample = mosaic(channels, levels)
    coefficients, fields, lifted_levels, cost = directions.lift(sample, levels, lifting, threshold)
    if check and not directions.pays(
        sample, coefficients, fields, levels, lifted_levels, threshold, frames, None, cost
    ):
        return plain, None, 0, None
    pairs = any(np.any(f >= len(SLOPES_97)) for f in fields)
    del sample, coefficients
    channels = [np.ascontiguousarray(x, dtype=np.float64) for x in channels]
    coefficients, fields = directions.chosen_analysis(channels, levels, lifted_levels, threshold, pairs)
    return coefficients, fields, lifted_levels, None
