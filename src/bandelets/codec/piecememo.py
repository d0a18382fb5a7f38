"""What the encodes of one piece at nearby thresholds share: a tile of a tiled image is coded once
per pass of rate control (:mod:`bandelets.codec.tile_encoder`), each pass a new
:func:`bandelets.codec.piece.encode_piece` at a threshold a few per cent from the last.

A piece coded at one threshold chooses its lifting's directions (:func:`bandelets.codec.alternatives.lifted`)
and its bandelet geometry (:func:`bandelets.search.basis.best_trees`) for that threshold: 70 % of
the CPU time of a 512 x 512 tile of the boombox map at 1 bpp. As a rate-control loop of one piece
reuses its first geometry (:class:`bandelets.search.treememo.TreeMemo`), a :class:`PieceMemo` kept
per tile across the passes hands a later pass the directions and the trees of the tile's first
pass, where its threshold is within :data:`bandelets.search.treememo.REUSE_WITHIN` (in ``log T``)
of that one's. Directions and trees are side information the file carries: any decode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..search.treememo import REUSE_WITHIN, TreeMemo
from ..transform.bandelets import padded_channels
from ..transform.directional import analysis

__all__ = ["PieceMemo"]


@dataclass
class PieceMemo:
    """The choices of one piece's first encode, for its encodes at nearby thresholds."""

    #: The bandelet geometry of the first bandelet encode (a :class:`TreeMemo` checks the threshold).
    trees: TreeMemo = field(default_factory=TreeMemo)
    #: The threshold, the count of wavelet levels and the levels lifted the directions were chosen
    #: for, and the directions (None: not lifted, the directions did not pay).
    lifting: tuple[float, int, int, list | None] | None = None

    def lifted(self, coded: np.ndarray, plain: list, levels: int, threshold: float):
        """The coefficients, directions and levels lifted of the channels ``coded`` (``plain``: their
        wavelet coefficients) with the directions of the first encode, or None where there are none
        for ``levels`` levels within :data:`REUSE_WITHIN` of ``threshold``."""
        if self.lifting is None:
            return None
        first, first_levels, lifted, fields = self.lifting
        if first_levels != levels or abs(math.log(threshold / first)) >= REUSE_WITHIN:
            return None
        if fields is None:
            return plain, None, 0
        return analysis(padded_channels(coded, levels), levels, lifted, fields)[0], fields, lifted

    def keep(self, threshold: float, levels: int, lifted: int, fields: list | None) -> None:
        """Keep the directions chosen at ``threshold`` (the first ones only)."""
        if self.lifting is None:
            self.lifting = (threshold, levels, lifted, fields)
