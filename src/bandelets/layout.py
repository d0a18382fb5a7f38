"""The coding order of a channel's coefficients, and the neighbours their contexts read.

Both the encoder and the decoder derive the same :class:`Plan` from the image size, the
number of levels and the quadtrees (which the decoder reads first). The approximation is
coded first, then the detail subbands from the coarsest level to the finest, H, V, D
within a level. Inside a subband the leaves of the quadtree come in coding order
(:meth:`bandelets.quadtree.Quadtree.leaves`), then the strip that the root squares do not
cover.

* A wavelet coefficient (approximation, NULL square, strip) is coded in raster order of
  its square; its neighbours are the left, upper, upper-left and upper-right coefficients
  of its subband, and its parent the coefficient at half its position in the next coarser
  subband of the same orientation.
* A bandelet square codes its 1D Haar coefficients coarse first (paper, step (9)); their
  neighbours are the previous coefficients of the same 1D scale, and their parents at the
  two coarser 1D scales. They are stored in zig-zag order inside the square.

The context class of a coefficient (:data:`bandelets.entropy.N_CLASSES` of them) tells the
coder which statistics it shares: approximation; wavelet detail by orientation and level;
bandelet by 1D scale counted from the finest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import zigzag
from .quadtree import Quadtree
from .wavelets import subband_slices

__all__ = ["Plan", "coding_plan"]


@dataclass(frozen=True)
class Plan:
    """Coding order of one channel.

    Attributes
    ----------
    order : ndarray of int64, shape (H*W,)
        Raveled Mallat-layout position of the i-th coded coefficient.
    classes : ndarray of int64, shape (H*W,)
        Context class of each.
    neighbours : ndarray of int64, shape (H*W, 5)
        Positions of its context neighbours, -1 where absent: two near, two farther, parent.
    """

    order: np.ndarray
    classes: np.ndarray
    neighbours: np.ndarray


def _raster_part(rows, cols, box, parent_box, width, cls):
    """Wavelet coefficients at subband coordinates ``rows, cols``; ``box`` = (y0, x0, h, w)."""
    y0, x0, h, w = box

    def at(r, c, ok):
        return np.where(ok, (y0 + r) * width + x0 + c, -1)

    neighbours = np.stack(
        [
            at(rows, cols - 1, cols > 0),
            at(rows - 1, cols, rows > 0),
            at(rows - 1, cols - 1, (rows > 0) & (cols > 0)),
            at(rows - 1, cols + 1, (rows > 0) & (cols + 1 < w)),
            np.full(rows.shape, -1)
            if parent_box is None
            else (parent_box[0] + rows // 2) * width + parent_box[1] + cols // 2,
        ],
        axis=-1,
    )
    return at(rows, cols, True), np.full(rows.shape, cls), neighbours


def _bandelet_part(rows, cols, square, box, width):
    """1D coefficients of bandelet squares of side ``square`` at subband ``rows, cols``."""
    y0, x0 = box[:2]
    n = square * square
    index = np.arange(n)
    scale = np.zeros(n, np.int64)
    scale[1:] = np.floor(np.log2(index[1:])).astype(np.int64)
    finest = int(np.log2(n)) - 1
    classes = np.where(index == 0, 14, 10 + np.minimum(finest - scale, 3))
    first = np.where(index == 0, 0, 1 << scale)  # first index of each 1D scale

    def rel(j, ok):
        return np.where(ok, j, -1)

    relative = np.stack(
        [
            rel(index - 1, index - 1 >= first),
            rel(index // 2, index >= 2),
            rel(index - 2, index - 2 >= first),
            rel(index // 2 + 1, (index >= 2) & (index // 2 + 1 < first)),
            rel(index // 4, index >= 4),
        ],
        axis=-1,
    )
    zz = zigzag(square)
    # Raveled position of the k-th stored coefficient of each square.
    local = (zz // square)[None, :] * width + (zz % square)[None, :]
    corner = ((y0 + rows) * width + x0 + cols)[:, None]
    where = corner + local
    neighbours = np.where(relative[None] >= 0, where[:, np.maximum(relative, 0)], -1)
    return where, np.broadcast_to(classes, where.shape), neighbours


def _subband_box(shape, level, orientation):
    height, width = shape
    h, w = height >> level, width >> level
    return ((0, w), (h, 0), (h, w))[orientation] + (h, w)


def coding_plan(shape: tuple[int, int], levels: int, trees: list[Quadtree]) -> Plan:
    """Coding plan of a padded channel of ``shape`` with its detail-subband quadtrees.

    Parameters
    ----------
    shape : (H, W)
        Padded channel size (multiples of ``2**levels``).
    levels : int
        Wavelet levels.
    trees : list of Quadtree
        One per detail subband, in :func:`bandelets.wavelets.subband_slices` order.
    """
    width = shape[1]
    pieces = []  # (rank key, positions, classes, neighbours), flattened per piece
    h, w = shape[0] >> levels, shape[1] >> levels
    rows, cols = np.divmod(np.arange(h * w), w)
    pieces.append(_raster_part(rows, cols, (0, 0, h, w), None, width, 0))
    for (level, orientation, _), tree in zip(subband_slices(shape, levels), trees, strict=True):
        box = _subband_box(shape, level, orientation)
        parent = _subband_box(shape, level + 1, orientation) if level < levels else None
        cls = 1 + orientation * 3 + min(level - 1, 2)
        lr, lc, lw, ld = tree.leaves()
        parts = []  # (leaf rank, within-leaf index, part)
        rank = np.arange(lr.shape[0])
        for size in np.unique(lw):
            for bandelet in (False, True):
                pick = (lw == size) & ((ld >= 0) == bandelet)
                if not pick.any():
                    continue
                if bandelet:
                    part = _bandelet_part(lr[pick], lc[pick], int(size), box, width)
                else:
                    sr, sc = np.divmod(np.arange(size * size), size)
                    part = _raster_part(
                        lr[pick, None] + sr[None, :], lc[pick, None] + sc[None, :], box, parent, width, cls
                    )
                parts.append((rank[pick], part))
        if parts:
            ranks = np.concatenate([np.repeat(r, p[0].shape[1]) for r, p in parts])
            inner = np.concatenate([np.tile(np.arange(p[0].shape[1]), len(r)) for r, p in parts])
            merged = [np.concatenate([p[k].reshape(-1, *p[k].shape[2:]) for _, p in parts]) for k in range(3)]
            order = np.lexsort((inner, ranks))
            pieces.append(tuple(m[order] for m in merged))
        covered_h, covered_w = tree.covered
        sr, sc = np.divmod(np.arange(box[2] * box[3]), box[3])
        strip = (sr >= covered_h) | (sc >= covered_w)
        pieces.append(_raster_part(sr[strip], sc[strip], box, parent, width, cls))
    order, classes, neighbours = (np.concatenate([p[k] for p in pieces]) for k in range(3))
    return Plan(order.astype(np.int64), classes.astype(np.int64), neighbours.astype(np.int64))
