"""What the encodes of one piece at nearby thresholds share: a tile of a tiled image is coded once
per pass of rate control (:mod:`bandelets.codec.tile_encoder`), each pass a new
:func:`bandelets.codec.piece.encode_piece` at a threshold a few per cent from the last.

A piece coded at one threshold chooses its lifting's directions (:func:`bandelets.codec.alternatives.lifted`)
and its bandelet geometry (:func:`bandelets.search.basis.best_trees`) for that threshold: 70 % of
the CPU time of a 512 x 512 tile of the boombox map at 1 bpp. As a rate-control loop of one piece
reuses its first geometry (:class:`bandelets.search.treememo.TreeMemo`), a :class:`PieceMemo` kept
per tile across the passes hands a later pass the directions and the trees of the tile's last
pass that chose them, where its threshold is within :data:`REUSE_WITHIN` (in ``log T``) of that
one's. Directions and trees are side information the file carries: any decode.

Why so close: choices reused 7.6 % of ``T`` away (the second pass of the 4096 x 4096 boombox at 1
bpp, ``bandelets.search.treememo.REUSE_WITHIN`` apart) made a file 3 % larger than choosing them
again (2,135,169 bytes against 2,072,953), which sent rate control to a third and a fourth pass
(the encode 168 s of CPU, 53.98 dB at 0.9848 bpp, against 134 s, 54.08 dB at 0.9885 bpp in two
passes choosing anew). Within 4 % (a third pass after a near miss, 1.2 to 2.7 % away in the runs
measured) a pass takes 30 to 40 % of the CPU time of one that chooses (BENCHMARKS.md, "Large maps").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..search.treememo import TreeMemo
from ..transform.bandelets import padded_channels
from ..transform.directional import analysis

__all__ = ["REUSE_WITHIN", "PieceMemo"]

#: Largest ``|log(T / T_chosen)|`` at which a pass reuses the choices of the last pass that made them.
REUSE_WITHIN = 0.04


@dataclass
class PieceMemo:
    """The choices of one piece's last encode that made them, for its encodes at nearby thresholds."""

    #: The bandelet geometry of its last searches (:meth:`bandelets.search.treememo.TreeMemo.search`,
    #: the search :func:`bandelets.codec.piece.encode_piece` gives the encode).
    trees: TreeMemo = field(default_factory=lambda: TreeMemo(REUSE_WITHIN))
    #: The threshold, the count of wavelet levels and the levels lifted the directions were chosen
    #: for, and the directions (None: not lifted, the directions did not pay).
    lifting: tuple[float, int, int, list | None] | None = None

    def lifted(self, coded: np.ndarray, plain: list, levels: int, threshold: float):
        """The coefficients, directions and levels lifted of the channels ``coded`` (``plain``: their
        wavelet coefficients) with the directions of the last encode that chose them, or None where
        there are none for ``levels`` levels within :data:`REUSE_WITHIN` of ``threshold``."""
        if self.lifting is None:
            return None
        first, first_levels, lifted, fields = self.lifting
        if first_levels != levels or abs(math.log(threshold / first)) >= REUSE_WITHIN:
            return None
        if fields is None:
            return plain, None, 0
        return analysis(padded_channels(coded, levels), levels, lifted, fields)[0], fields, lifted

    def keep(self, threshold: float, levels: int, lifted: int, fields: list | None) -> None:
        """Keep the directions chosen at ``threshold`` (in place of those kept before)."""
        self.lifting = (threshold, levels, lifted, fields)
