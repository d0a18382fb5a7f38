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

The context class of a coefficient (:data:`bandelets.coding.coefficients.N_CLASSES` of them) tells the
coder which statistics it shares: approximation; wavelet detail by orientation and level;
bandelet by 1D scale counted from the finest.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from ..transform.bandeletize import ORDER
from ..transform.geometry import zigzag
from ..transform.quadtree import MAX_WIDTH, MIN_WIDTH, Quadtree
from ..transform.wavelets import subband_slices

__all__ = ["Segment", "approximation_plan", "subband_box", "subband_plan"]


_MAX_LEVELS = (MAX_WIDTH // MIN_WIDTH).bit_length()  # square sides 4 .. MAX_WIDTH


@dataclass(frozen=True)
class Segment:
    """Coding order of a run of coefficients of one channel.

    Attributes
    ----------
    order : ndarray of int64, shape (n,)
        Raveled Mallat-layout position of the i-th coded coefficient.
    classes : ndarray of int64, shape (n,)
        Context class of each.
    neighbours : ndarray of int64, shape (n, 6)
        Positions of its context neighbours, -1 where absent: two near, two farther, parent, and
        the same position in the subband of the same level coded before (wavelet coefficients).
    """

    order: np.ndarray
    classes: np.ndarray
    neighbours: np.ndarray


@njit(cache=True, nogil=True)
def _raster_part(skip, box, parent_box, width, cls, sibling_box):
    """Wavelet coefficients of the subband ``box`` = (y0, x0, h, w) where ``skip`` (h, w) is
    False, in raster order; ``parent_box`` (y0, x0) of the coarser subband, or empty;
    ``sibling_box`` (y0, x0) of the subband of the same level coded just before, or empty."""
    y0, x0, h, w = box
    n = skip.size - np.count_nonzero(skip)
    order = np.empty(n, np.int64)
    neighbours = np.empty((n, 6), np.int64)
    i = 0
    for r in range(h):
        for c in range(w):
            if skip[r, c]:
                continue
            at = (y0 + r) * width + x0 + c
            order[i] = at
            neighbours[i, 0] = at - 1 if c > 0 else -1
            neighbours[i, 1] = at - width if r > 0 else -1
            neighbours[i, 2] = at - width - 1 if r > 0 and c > 0 else -1
            neighbours[i, 3] = at - width + 1 if r > 0 and c + 1 < w else -1
            neighbours[i, 4] = (
                (parent_box[0] + r // 2) * width + parent_box[1] + c // 2 if parent_box.size else -1
            )
            neighbours[i, 5] = (sibling_box[0] + r) * width + sibling_box[1] + c if sibling_box.size else -1
            i += 1
    return order, np.full(n, cls, np.int64), neighbours


# Bounded: the key holds the channel width, and a process decoding files of many widths (a server,
# the fuzzer: +530 MB over 1.2 million inputs) would otherwise keep the tables of every one.
@lru_cache(maxsize=256)
def _square_tables(square: int, k: int, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coding order of the 1D coefficients (order ``k``) of a bandelet square of side ``square``
    in a channel ``width`` wide: raveled offset of each from the square's corner, context class
    of each, and the index of each of its 5 neighbours among them (-1 where absent)."""
    n = square * square
    index = np.arange(n)
    scale = np.zeros(n, np.int64)  # 1D scale: wavelets of scale s start at k 2**s
    scale[k:] = np.floor(np.log2(index[k:] // k)).astype(np.int64)
    finest = int(np.log2(n // k)) - 1
    classes = 16 + 5 * min(square.bit_length() - 3, 2) + np.where(index < k, 4, np.minimum(finest - scale, 3))
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
    # Raveled position of the k-th stored coefficient, from the square's corner.
    local = (zz // square) * width + zz % square
    return local.astype(np.int64), classes.astype(np.int64), relative.astype(np.int64)


@njit(cache=True, nogil=True)
def _bandelet_part(in_square, top, left, sizes, box, width, tables):
    """1D coefficients of the bandelet squares (corners ``top, left``, sides ``sizes``, in
    coding order), each square's coarse first; marks the squares in ``in_square``.
    ``tables[j]`` are the :func:`_square_tables` of side ``MIN_WIDTH << j``."""
    n = 0
    for s in range(top.shape[0]):
        n += sizes[s] * sizes[s]
    order = np.empty(n, np.int64)
    classes = np.empty(n, np.int64)
    neighbours = np.full((n, 6), -1, np.int64)
    i = 0
    for s in range(top.shape[0]):
        size = sizes[s]
        in_square[top[s] : top[s] + size, left[s] : left[s] + size] = True
        local, cls, relative = tables[int(np.log2(size // MIN_WIDTH))]
        corner = (box[0] + top[s]) * width + box[1] + left[s]
        for j in range(size * size):
            order[i + j] = corner + local[j]
            classes[i + j] = cls[j]
            for m in range(5):
                neighbours[i + j, m] = corner + local[relative[j, m]] if relative[j, m] >= 0 else -1
        i += size * size
    return order, classes, neighbours


def subband_box(shape: tuple[int, int], level: int, orientation: int) -> tuple[int, int, int, int]:
    """``top, left, height, width`` of the detail subband of ``level`` (1 = finest) and
    ``orientation`` (0 H, 1 V, 2 D) in the Mallat layout of a padded ``shape``."""
    height, width = shape
    h, w = height >> level, width >> level
    return ((0, w), (h, 0), (h, w))[orientation] + (h, w)


def approximation_plan(shape: tuple[int, int], levels: int) -> Segment:
    """Coding order of the approximation subband of a padded channel of ``shape``."""
    h, w = shape[0] >> levels, shape[1] >> levels
    everything = np.zeros((h, w), np.bool_)
    none = np.zeros(0, np.int64)
    return Segment(*_raster_part(everything, (0, 0, h, w), none, shape[1], 0, none))


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
        Position of the subband in :func:`bandelets.transform.wavelets.subband_slices`.
    tree : Quadtree
        Its quadtree.
    transform_1d : str
        The 1D transform of the bandelet squares (sets where its scales start).
    """
    k = ORDER[transform_1d]
    level, orientation, _ = subband_slices(shape, levels)[index]
    box = subband_box(shape, level, orientation)
    parent = np.array(subband_box(shape, level + 1, orientation)[:2] if level < levels else (), np.int64)
    top, left, sizes, dirs = tree.leaves()
    bandelet = dirs >= 0
    in_square = np.zeros(box[2:], np.bool_)
    tables = tuple(_square_tables(MIN_WIDTH << j, k, shape[1]) for j in range(_MAX_LEVELS))
    squares = _bandelet_part(in_square, top[bandelet], left[bandelet], sizes[bandelet], box, shape[1], tables)
    sibling = np.array(subband_box(shape, level, orientation - 1)[:2] if orientation else (), np.int64)
    rest = _raster_part(in_square, box, parent, shape[1], 1 + orientation * 5 + min(level - 1, 4), sibling)
    return Segment(*squares), Segment(*rest)
