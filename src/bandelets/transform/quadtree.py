"""Step (10), section 5 of the paper: the best dyadic segmentation of a subband.

The squares of a subband form a quadtree whose roots have width :func:`root_width` and
whose smallest leaves have width 4. Given, for every dyadic square ``S`` of every width,
its best Lagrangian ``L(S)`` and direction, :func:`best_quadtree` runs the paper's bottom-up
merge: the four children of ``S`` are merged when ``L(S) < L0(S1) + ... + L0(S4) + lambda T^2``
(the 1-bit split cost), and ``L0(S) = min(L(S), L'(S))``.

A quadtree is stored level by level (level 0 holds the width-4 squares): one boolean leaf
mask and one direction map per level. Split flags are coded level by level, coarse to fine,
each level in raster order of the nodes that exist there.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

__all__ = ["MIN_WIDTH", "MAX_WIDTH", "Quadtree", "root_width", "flat_quadtree", "morton"]

#: Smallest square width, as in the paper.
MIN_WIDTH = 4


#: Largest square width: 1232 directions at 32, and the search cost grows as L**2 per sample.
MAX_WIDTH = 32


def root_width(shape: tuple[int, int]) -> int:
    """Width of the root squares of a subband of ``shape``; 0 when it is too small.

    The paper bounds ``4 <= L <= sqrt(subband width)``. Larger squares follow straight
    creases further and measurably pay here (+0.2 to +0.4 dB BD-PSNR on the generated crease
    map), so the bound used is the larger of ``sqrt(width)`` and ``width / 8``, capped at
    :data:`MAX_WIDTH`; the shorter side counts for non-square subbands.
    """
    side = min(shape)
    width = 0
    candidate = MIN_WIDTH
    while candidate <= MAX_WIDTH and (candidate * candidate <= side or 8 * candidate <= side):
        width = candidate
        candidate *= 2
    return width


def _upsample(mask: np.ndarray) -> np.ndarray:
    return mask.repeat(2, axis=0).repeat(2, axis=1)


@dataclass(frozen=True)
class Quadtree:
    """Segmentation of one subband into squares, with a direction per leaf.

    Attributes
    ----------
    root : int
        Width of the root squares (0: the subband has no squares and stays wavelet).
    leaf : tuple of ndarray of bool
        ``leaf[l]`` has shape ``(rows / w_l, cols / w_l)`` over the covered region, with
        ``w_l = 4 * 2**l``; True where a leaf of width ``w_l`` starts.
    direction : tuple of ndarray of int
        Same shapes; the direction index of each leaf (-1 for NULL), meaningless elsewhere.
    """

    root: int
    leaf: tuple
    direction: tuple

    @property
    def covered(self) -> tuple[int, int]:
        """Shape of the region tiled by the root squares (the rest stays wavelet)."""
        if not self.leaf:
            return (0, 0)
        rows, cols = self.leaf[0].shape
        return rows * MIN_WIDTH, cols * MIN_WIDTH

    def open_nodes(self) -> list[np.ndarray]:
        """Per level, True at the nodes that exist (no ancestor is a leaf)."""
        out = [np.zeros(0, bool)] * len(self.leaf)
        top = len(self.leaf) - 1
        if top < 0:
            return out
        out[top] = np.ones_like(self.leaf[top])
        for level in range(top, 0, -1):
            out[level - 1] = _upsample(out[level] & ~self.leaf[level])
        return out

    @cached_property
    def _leaves(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.find_leaves()

    def leaves(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``rows, cols, widths, directions`` of every leaf, in coding order (see ``find_leaves``).

        Computed once per quadtree; the arrays are shared, do not modify them.
        """
        return self._leaves

    @cached_property
    def squares(self) -> tuple[tuple[int, np.ndarray, np.ndarray, np.ndarray], ...]:
        """``(width, rows, cols, directions)`` of the leaves that have a direction, one entry per
        width (ascending), each in coding order. Computed once per quadtree (the restoration
        transforms with the same trees at every iteration); the arrays are shared."""
        rows, cols, widths, dirs = self.leaves()
        out = []
        for width in np.unique(widths[dirs >= 0]):
            pick = (widths == width) & (dirs >= 0)
            out.append((int(width), rows[pick], cols[pick], dirs[pick]))
        return tuple(out)

    def find_leaves(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``rows, cols, widths, directions`` of every leaf, in coding order.

        Coding order is raster order of the root squares, then Z (Morton) order inside a
        root: every leaf comes after the leaves holding its upper and left neighbours.
        """
        parts = []
        opened = self.open_nodes()
        for level, (leaf, d) in enumerate(zip(self.leaf, self.direction, strict=True)):
            r, c = np.nonzero(leaf & opened[level])
            width = MIN_WIDTH << level
            parts.append((r * width, c * width, np.full(r.shape, width), d[r, c]))
        if not parts:
            empty = np.zeros(0, np.int64)
            return empty, empty, empty, empty
        rows, cols, widths, dirs = (np.concatenate(p) for p in zip(*parts, strict=True))
        roots_per_row = self.covered[1] // self.root
        root_index = (rows // self.root) * roots_per_row + cols // self.root
        order = np.lexsort((morton((rows % self.root) // 4, (cols % self.root) // 4), root_index))
        return rows[order], cols[order], widths[order], dirs[order].astype(np.int64)


def morton(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Morton (Z-order) code of every cell ``rows, cols``: the bits of the two interleaved."""
    code = np.zeros(rows.shape, np.int64)
    top = int(max(rows.max(initial=0), cols.max(initial=0)))
    for bit in range(top.bit_length()):
        code |= ((cols >> bit) & 1) << (2 * bit)
        code |= ((rows >> bit) & 1) << (2 * bit + 1)
    return code


def flat_quadtree(shape: tuple[int, int], root: int) -> Quadtree:
    """Quadtree whose leaves are the root squares, all NULL: the wavelet basis."""
    if root == 0:
        return Quadtree(0, (), ())
    levels = root.bit_length() - MIN_WIDTH.bit_length() + 1
    leaf, direction = [], []
    for level in range(levels):
        width = MIN_WIDTH << level
        cells = (shape[0] // root * root // width, shape[1] // root * root // width)
        leaf.append(np.full(cells, level == levels - 1))
        direction.append(np.full(cells, -1, np.int64))
    return Quadtree(root, tuple(leaf), tuple(direction))
