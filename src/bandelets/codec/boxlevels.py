"""The image at a coarser level of a file whose wavelet's analysis low-pass is a box average
(:data:`bandelets.format.fields.BOX_WAVELETS`, ``encode(box_mips=True)``; issue 39).

With such a wavelet the approximation of ``k`` levels is ``2**k`` times the ``2**k x 2**k`` box average
of each channel, and the detail levels coarser than ``k`` (the first bytes of the file) are the
transform of ``L - k`` levels of that ``2**k``-scaled mip. So the level image needs no filter towards
box averages (:func:`bandelets.transform.coarse.box_filtered`): it is the box mip of the decoded image
before restoration, to the last digits (a biorthogonal transform's analysis undoes its synthesis).
And it can be restored like the full image (:mod:`bandelets.restore.restoration`): the coarse bins,
at threshold ``T / 2**k`` for the mip itself, with the file's iterations, its bandelet trees and local
frames, no unit length (a box average of unit vectors is shorter). On the shared leather map at 0.5
bpp this brings the level-1 image's excess over the restored full decode's box mip (their mean angles
from the original's) from 0.13 to 0.03 degree (BENCHMARKS, "Box mips from a prefix").
"""

from __future__ import annotations

from itertools import islice

import numpy as np

from ..format.fields import BOX_WAVELETS
from ..format.header import Header
from ..restore import restoration
from ..transform import frames
from ..transform.bandeletize import bandeletize, debandeletize
from ..transform.bandelets import apply_trees
from ..transform.wavelets import wavedec, waverec

__all__ = ["box_level", "has_box_levels"]


def has_box_levels(header: Header) -> bool:
    """Whether the level images of a file are box mips (:func:`box_level`): a box wavelet, no
    directions, no Riesz pair (both change what the approximation averages)."""
    return header.wavelet in BOX_WAVELETS and not header.lifting and not header.riesz


def box_level(
    header: Header, trees: list, bins: list[np.ndarray], coarse: list[np.ndarray], found: dict, level: int
) -> np.ndarray:
    """The channels at ``level`` of a file with :func:`has_box_levels`: its box mips, restored.

    Parameters
    ----------
    header, trees
        The file's.
    bins : list of ndarray of int, shape (H', W') each
        Every channel's bin indices (the padded size; only the levels coarser than ``level`` read).
    coarse : list of ndarray, shape (H' >> level, W' >> level)
        Every channel's dequantized coefficients of those levels, trees undone, in the global frame.
    found : dict
        The local frames of every level coarser than ``level`` (none without frames).
    level : int

    Returns
    -------
    ndarray, shape (C, H' >> level, W' >> level), float64: the box averages of the channels.
    """
    levels, scale = header.levels - level, float(1 << level)
    turned = {lev - level: f for lev, f in found.items()}  # the same subbands, numbered in the block
    args, t1d, weight = (header.wavelet, levels, header.extension), header.transform_1d, header.normal_weight

    def analysis(x: np.ndarray) -> np.ndarray:
        for channel in x:
            wavedec(channel, *args, out=channel)
        if turned:
            frames.rotate_levels(list(x), turned, levels, weight, local=True)
        for channel in x:
            apply_trees(channel, levels, trees, bandeletize, t1d, inplace=True)
        return x

    def synthesis(c: np.ndarray) -> np.ndarray:
        for channel in c:
            apply_trees(channel, levels, trees, debandeletize, t1d, inplace=True)
        if turned:
            frames.rotate_levels(list(c), turned, levels, weight, local=False)
        for channel in c:
            waverec(channel, *args, out=channel)
        return c

    if not header.restoration:
        return np.stack([waverec(np.ascontiguousarray(c), *args) for c in coarse]) / scale
    h, w = coarse[0].shape
    block = [np.ascontiguousarray(b[:h, :w]) for b in bins]
    steps = restoration.iterate(
        block,
        header.threshold / scale,
        analysis,
        synthesis,
        folded=header.folded,
        second_across=header.folded,
    )
    return np.array(next(islice(steps, header.restoration, None)), np.float64)
