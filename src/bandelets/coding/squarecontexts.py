"""What the context models of the 1D bandelet coefficients read around their square.

Inside a bandelet square, the 1D coefficients (:mod:`bandelets.transform.bandeletize`) have neither
2D neighbours nor a 2D parent: :mod:`bandelets.coding.order` gives them their 1D neighbours (the
previous coefficients of their 1D scale, their parents at the coarser 1D scales) and the guide
channel its coefficient at the same place. Two more things are decoded before a square, and
tell where its significant coefficients are:

* the sibling subband (the subband of the same level coded just before: H for V, V for D),
  whose wavelet bins in the square, read along the square's direction and transformed by the
  same 1D transform, predict each 1D coefficient's magnitude (a crease crosses the three
  subbands of a level at the same place);
* the parent subband (the same orientation, one level coarser): the largest bin magnitude
  under the coefficient's support (the samples of the reordered square it is made of).

:func:`square_hints` turns both into a small integer per coefficient, the *hint*, which
:func:`bandelets.coding.coefficients.code_coefficients` adds to the significance context of the bandelet
classes; it also marks the first coefficient of every square, where the sign model restarts
(the signs of the two channels of a normal map agree or disagree square by square).
Measured on the four maps of ``benchmarks/fixed_threshold_rd.py`` (BENCHMARKS, "Contexts for
the bandelet coefficients").
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..format.quantizer import RECONSTRUCTION
from ..transform.bandeletize import ORDER, alpert_matrices, multiwavelet
from ..transform.geometry import directions
from ..transform.quadtree import MAX_WIDTH, MIN_WIDTH, Quadtree
from ..transform.wavelets import subband_slices
from .coefficients import N_HINTS, SQUARE_START
from .order import subband_box

__all__ = ["square_hints"]

_PREDICTED_EDGES = np.array([1.0, 2.0, 4.0, 8.0])  # of the predicted 1D magnitude, in bins
_N_PREDICTED = _PREDICTED_EDGES.shape[0] + 2  # the buckets, and "no sibling subband"
_N_PARENT = 4  # largest parent bin magnitude under the support: 0, 1, 2+, or no parent subband
assert _N_PREDICTED * _N_PARENT == N_HINTS  # the coder's tables hold that many
_MAX_LEVELS = (MAX_WIDTH // MIN_WIDTH).bit_length()
# Stand-ins for the widths a subband does not use, read-only as the cached tables are (one type).
_NONE_ORDERS = np.zeros((0, 0), np.int32)
_NONE_MATS = np.zeros((0, 0, 0))
_NONE_ORDERS.flags.writeable = _NONE_MATS.flags.writeable = False


@njit(cache=True, nogil=True)
def _hints(out, known, width, top, left, sizes, dirs, sibling, parent, orders, mats, k):
    """Hints of the squares (corners ``top, left`` in their subband, sides ``sizes``, directions
    ``dirs``, in coding order) into ``out``; ``sibling`` and ``parent`` are the (y0, x0) of those
    subbands in the raveled layout ``known`` of ``width`` columns, or empty."""
    most = MAX_WIDTH * MAX_WIDTH
    v, tmp, predicted = np.empty(most), np.empty(most), np.empty(most)
    # The largest parent magnitude (capped at 2) over each dyadic group of the reordered samples,
    # as a heap: node 1 the whole square, nodes 2 g and 2 g + 1 the halves of node g, leaves n + t.
    # Each coefficient's support is one node: O(n) a square, not O(k n log n) for the scans.
    largest = np.empty(2 * most, np.int64)
    i = 0
    for s in range(top.shape[0]):
        size = sizes[s]
        n = size * size
        j_width = int(np.log2(size // MIN_WIDTH))
        order = orders[j_width][dirs[s]]
        if sibling.size:
            for t in range(n):
                r, c = order[t] // size, order[t] % size
                q = known[(sibling[0] + top[s] + r) * width + sibling[1] + left[s] + c]
                x = (abs(q) + RECONSTRUCTION) if q != 0 else 0.0
                v[t] = x if q > 0 else -x
            multiwavelet(v[:n], tmp[:n], predicted[:n], mats[j_width])
        if parent.size:
            for t in range(n):
                r = (top[s] + order[t] // size) // 2
                c = (left[s] + order[t] % size) // 2
                largest[n + t] = min(abs(known[(parent[0] + r) * width + parent[1] + c]), 2)
            for node in range(n - 1, 0, -1):
                largest[node] = max(largest[2 * node], largest[2 * node + 1])
        for j in range(n):
            if sibling.size:
                p = abs(predicted[j])
                bucket = 0
                while bucket < _PREDICTED_EDGES.shape[0] and p >= _PREDICTED_EDGES[bucket]:
                    bucket += 1
            else:
                bucket = _N_PREDICTED - 1
            if parent.size:
                # Support of coefficient j: the whole square for the k scaling functions, else
                # group g of the 2**scale groups of n / 2**scale reordered samples.
                node = 1
                if j >= k:
                    scale = int(np.log2(j // k))
                    node = (1 << scale) + (j - (k << scale)) // k
                above = largest[node]
            else:
                above = _N_PARENT - 1
            out[i + j] = bucket * _N_PARENT + above + (SQUARE_START if j == 0 else 0)
        i += n


def square_hints(
    known: np.ndarray, shape: tuple[int, int], levels: int, index: int, tree: Quadtree, transform_1d: str
) -> np.ndarray:
    """Hints of the 1D coefficients of the bandelet squares of detail subband ``index``.

    Parameters
    ----------
    known : ndarray of int64, shape (H * W,)
        What the context models of the channel see: the bins decoded so far, the coarser
        subbands and the subbands of the same level coded before in wavelet form.
    shape : (H, W)
        Padded channel size.
    levels : int
        Wavelet levels.
    index : int
        Position of the subband in :func:`bandelets.transform.wavelets.subband_slices`.
    tree : Quadtree
        Its quadtree.
    transform_1d : str
        The 1D transform of the bandelet squares.

    Returns
    -------
    ndarray of int64, shape (n,): in the order of the squares' segment of
    :func:`bandelets.coding.order.subband_plan`, ``predicted * 4 + parent`` (<
    :data:`bandelets.coding.coefficients.N_HINTS`),
    plus :data:`bandelets.coding.coefficients.SQUARE_START` at the first coefficient of each square.
    """
    level, orientation, _ = subband_slices(shape, levels)[index]
    top, left, sizes, dirs = tree.leaves()
    bandelet = dirs >= 0
    out = np.zeros(int(np.sum(sizes[bandelet] ** 2)), np.int64)
    if out.size == 0:
        return out
    k = ORDER[transform_1d]
    sibling = np.array(subband_box(shape, level, orientation - 1)[:2] if orientation else (), np.int64)
    parent = np.array(subband_box(shape, level + 1, orientation)[:2] if level < levels else (), np.int64)
    # Only the widths used: the reorderings of the wider squares are long to list.
    used = set(sizes[bandelet].tolist())
    widths = [MIN_WIDTH << j for j in range(_MAX_LEVELS)]
    orders = tuple(directions(w)[1] if w in used else _NONE_ORDERS for w in widths)
    mats = tuple(alpert_matrices(w * w, k) if w in used else _NONE_MATS for w in widths)
    _hints(
        out,
        known,
        shape[1],
        top[bandelet],
        left[bandelet],
        sizes[bandelet],
        dirs[bandelet],
        sibling,
        parent,
        orders,
        mats,
        k,
    )
    return out
