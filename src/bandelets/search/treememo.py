"""The direction search of a rate-control loop done once: its later encodes reuse the trees.

Rate control (:func:`bandelets.ratecontrol.for_size`) encodes the same coefficients at a few
thresholds, close to one another once the first file is made (on the shared real 512 x 512 maps
at 0.5 to 2 bpp the first file missed the size window by 1 to 13 %: the second threshold is
within a few per cent of the first). Each encode searched the bandelet geometry again (the
quadtrees and directions of :func:`bandelets.transform.best_trees`, 36 to 43 % of the CPU
time of a 1 bpp encode of those maps), for nearly the same choice: the Lagrangian
``error + lambda T**2 bits`` of a square moves little with ``T`` across a few per cent. A
:class:`TreeMemo`, made for one loop, searches the geometry at the loop's first bandelet encode
and hands the same trees to the later encodes whose threshold is within :data:`REUSE_WITHIN` (in
``log T``) of it (of the nearest threshold searched, where a later one searched again); the
wavelet files of the size probe have no geometry and are not counted.
The trees are side information the file carries: any trees decode, and these were optimal a few
per cent of ``T`` away.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable

import numpy as np

from .basis import best_trees

__all__ = ["REUSE_WITHIN", "TreeMemo"]

#: Largest ``|log(T / T_searched)|`` at which a loop's later encode reuses the trees of a search.
REUSE_WITHIN = 0.15

#: Searches a memo keeps (the latest): the first file of a loop and the one that corrected it.
KEPT = 2


class TreeMemo:
    """The trees of the bandelet encodes of one rate-control loop that searched, for its later ones.

    :meth:`search` has the signature of :func:`bandelets.transform.best_trees`; make one memo per
    set of coefficients (a loop of rate control), never share one across coefficients.

    Parameters
    ----------
    within : float
        :data:`REUSE_WITHIN` unless given: 0 searches at every threshold (the memo does nothing).
    """

    def __init__(self, within: float = REUSE_WITHIN) -> None:
        self.within = within
        #: ``(threshold, key, trees)`` of the last :data:`KEPT` searches, in order.
        self.searches: list[tuple[float, tuple, list]] = []
        #: Searches made and reused (for benchmarks and tests).
        self.searched = 0
        self.reused = 0

    def search(
        self,
        coefficients: list[np.ndarray],
        levels: int,
        threshold: float,
        transform: str,
        transform_1d: str,
        before: Callable | None = None,
    ) -> list:
        """The trees of :func:`bandelets.transform.best_trees` at ``threshold``, or those of the
        memo's search nearest to it in ``log T`` where that is within :attr:`within` (then ``before``
        is called for every subband with them, as the search would have). Nearest, not first: a
        loop whose first file missed by more than the window (the hard-surface variant of the vent
        decal: 13 % small) searches at its second threshold, and its third, a few per cent away,
        reuses that (0.5 s of CPU at 512 x 512)."""
        key = (levels, transform, transform_1d, tuple(c.shape for c in coefficients))
        if transform != "wavelet":
            near = [(abs(math.log(threshold / t)), trees) for t, k, trees in self.searches if k == key]
            distance, trees = min(near, key=lambda found: found[0], default=(math.inf, None))
            if distance < self.within:
                trees = copy.deepcopy(trees)
                if before is not None:
                    for index in range(len(trees)):
                        before(index, trees)
                self.reused += 1
                return trees
        trees = best_trees(coefficients, levels, threshold, transform, transform_1d, before)
        if transform != "wavelet":
            self.searched += 1
            # The last KEPT searches (a tile's memo lives through every pass of a large image).
            self.searches = [*self.searches, (threshold, key, copy.deepcopy(trees))][-KEPT:]
        return trees
