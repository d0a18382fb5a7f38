"""The coding order of a channel's coefficients, and the neighbours their contexts read.

Both the encoder and the decoder derive the same :class:`Segment` lists from the image
size, the number of levels and the quadtree of each subband (which the decoder reads just
before the subband). The approximation is
coded first, then the detail subbands from the coarsest level to the finest, H, V, D
within a level. Inside a subband:

1. the bandelet squares, in the coding order of the quadtree's leaves, each one's 1D
   coefficients coarse first (paper, step (9)); a coefficient's neighbours are the previous
   coefficients of its 1D scale and its parents at the two coarser 1D scales. They are
   stored in zig-zag order inside the square.
2. then every other coefficient of the subband in raster order, as a plain wavelet coder
   would: neighbours are the left, upper, upper-left and upper-right coefficients, the
   parent the coefficient at half its position in the next coarser subband of the same
   orientation.

Between the two, the codec replaces what the context models see inside the bandelet
squares by the (quantized) wavelet coefficients their decoded bandelet coefficients give
back: the wavelet coefficients around a bandelet square, and the finer subbands below it,
then read meaningful neighbours and parents instead of 1D coefficients laid out in zig-zag.

The context class of a coefficient (:data:`bandelets.entropy.N_CLASSES` of them) tells the
coder which statistics it shares: approximation; wavelet detail by orientation and level;
bandelet by 1D scale counted from the finest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bandeletize import TRANSFORMS_1D
from .geometry import zigzag
from .quadtree import Quadtree
from .wavelets import subband_slices

__all__ = ["Segment", "approximation_plan", "subband_plan"]


@dataclass(frozen=True)
class Segment:
    """Coding order of a run of coefficients of one channel.

    Attributes
    ----------
    order : ndarray of int64, shape (n,)
        Raveled Mallat-layout position of the i-th coded coefficient.
    classes : ndarray of int64, shape (n,)
        Context class of each.
    neighbours : ndarray of int64, shape (n, 5)
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


def _bandelet_part(rows, cols, square, box, width, k):
    """1D coefficients (order ``k``) of bandelet squares of side ``square`` at ``rows, cols``."""
    y0, x0 = box[:2]
    n = square * square
    index = np.arange(n)
    scale = np.zeros(n, np.int64)  # 1D scale: wavelets of scale s start at k 2**s
    scale[k:] = np.floor(np.log2(index[k:] // k)).astype(np.int64)
    finest = int(np.log2(n // k)) - 1
    classes = 10 + 5 * min(square.bit_length() - 3, 2) + np.where(index < k, 4, np.minimum(finest - scale, 3))
    first = np.where(index < k, 0, k << scale)  # first index of each 1D scale

    def rel(j, ok):
        return np.where(ok, j, -1)

    relative = np.stack(
        [
            rel(index - 1, index - 1 >= first),
            rel(index // 2, index >= 2 * k),
            rel(index - 2, index - 2 >= first),
            rel(index // 2 + 1, (index >= 2 * k) & (index // 2 + 1 < first)),
            rel(index // 4, index >= 4 * k),
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


def _segment(part) -> Segment:
    order, classes, neighbours = part
    return Segment(
        order.astype(np.int64).ravel(),
        np.asarray(classes, np.int64).ravel(),
        neighbours.astype(np.int64).reshape(-1, 5),
    )


def approximation_plan(shape: tuple[int, int], levels: int) -> Segment:
    """Coding order of the approximation subband of a padded channel of ``shape``."""
    h, w = shape[0] >> levels, shape[1] >> levels
    rows, cols = np.divmod(np.arange(h * w), w)
    return _segment(_raster_part(rows, cols, (0, 0, h, w), None, shape[1], 0))


def subband_plan(
    shape: tuple[int, int], levels: int, index: int, tree: Quadtree, transform_1d: str
) -> tuple[Segment, Segment]:
    """Coding order of detail subband number ``index``: its bandelet squares, then the rest.

    Parameters
    ----------
    shape : (H, W)
        Padded channel size (multiples of ``2**levels``).
    levels : int
        Wavelet levels.
    index : int
        Position of the subband in :func:`bandelets.wavelets.subband_slices`.
    tree : Quadtree
        Its quadtree.
    transform_1d : str
        The 1D transform of the bandelet squares (sets where its scales start).
    """
    k = TRANSFORMS_1D.index(transform_1d) + 1
    level, orientation, _ = subband_slices(shape, levels)[index]
    box = _subband_box(shape, level, orientation)
    parent = _subband_box(shape, level + 1, orientation) if level < levels else None
    top, left, sizes, dirs = tree.leaves()
    in_square = np.zeros(box[2:], bool)
    rank = np.arange(top.shape[0])
    parts = []
    for size in np.unique(sizes[dirs >= 0]):
        pick = (sizes == size) & (dirs >= 0)
        parts.append((rank[pick], _bandelet_part(top[pick], left[pick], int(size), box, shape[1], k)))
        for r0, c0 in zip(top[pick], left[pick], strict=True):
            in_square[r0 : r0 + size, c0 : c0 + size] = True
    if parts:
        ranks = np.concatenate([np.repeat(r, p[0].shape[1]) for r, p in parts])
        inner = np.concatenate([np.tile(np.arange(p[0].shape[1]), len(r)) for r, p in parts])
        sort = np.lexsort((inner, ranks))
        squares = tuple(
            np.concatenate([p[j].reshape(-1, *p[j].shape[2:]) for _, p in parts])[sort] for j in range(3)
        )
    else:
        squares = (np.zeros(0), np.zeros(0), np.zeros((0, 5)))
    rows, cols = np.nonzero(~in_square)
    rest = _raster_part(rows, cols, box, parent, shape[1], 1 + orientation * 3 + min(level - 1, 2))
    return _segment(squares), _segment(rest)
