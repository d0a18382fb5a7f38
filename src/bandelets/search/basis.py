"""Steps (8) and (10) of the paper: the best bandelet basis of a channel for a threshold ``T``.

In every detail subband, the Lagrangian ``D + lambda T**2 R`` of every dyadic square for each of
its directions (:mod:`bandelets.search.lagrangian`), then the paper's bottom-up merge of the squares
into the quadtree of least Lagrangian (:func:`best_quadtree`). :func:`best_trees` runs it on
coefficients already transformed (the encoder); :func:`forward` is the whole forward transform of one
channel in its best basis, the inverse of :func:`bandelets.transform.bandelets.inverse`.
"""

from __future__ import annotations

import numpy as np

from ..coding.trees import predicted_directions, reference_of
from ..format.checks import check_image, check_options, check_threshold
from ..format.fields import DEFAULT_TRANSFORM_1D, DEFAULT_WAVELET, Transform1D, Wavelet
from ..transform.bandeletize import bandeletize
from ..transform.bandelets import Bandelets, apply_trees, inverse, pad_channel
from ..transform.geometry import directions, nearest_direction
from ..transform.quadtree import MIN_WIDTH, Quadtree, flat_quadtree, root_width
from ..transform.wavelets import max_levels, subband_slices, wavedec
from .lagrangian import GEOMETRY_PRICE, LAMBDA, best_directions

__all__ = ["best_quadtree", "best_trees", "forward", "inverse"]


def best_quadtree(costs: list[np.ndarray], dirs: list[np.ndarray], split_cost: float) -> Quadtree:
    """Paper's bottom-up merge.

    Parameters
    ----------
    costs : list of ndarray
        ``costs[l]``, shape ``(R / w_l, C / w_l)``: best Lagrangian of each square of width
        ``w_l = 4 * 2**l`` over the covered ``R x C`` region, for ``l = 0 .. n_levels - 1``.
    dirs : list of ndarray of int
        The direction achieving it (-1 for NULL), same shapes.
    split_cost : float
        Lagrangian price of a split, ``lambda T**2`` for the paper's 1 bit.

    Returns
    -------
    Quadtree
    """
    if not costs:
        return flat_quadtree((0, 0), 0)
    best = costs[0]
    merged = [np.ones(costs[0].shape, bool)]
    for level in range(1, len(costs)):
        rows, cols = costs[level].shape
        children = best.reshape(rows, 2, cols, 2).sum(axis=(1, 3)) + split_cost
        merge = costs[level] < children
        merged.append(merge)
        best = np.where(merge, costs[level], children)
    root = MIN_WIDTH << (len(costs) - 1)
    return Quadtree(root, tuple(merged), tuple(np.asarray(d, np.int64) for d in dirs))


def best_trees(
    coefficients: list[np.ndarray],
    levels: int,
    threshold: float,
    transform: str,
    transform_1d: str,
    before=None,
) -> list:
    """Best quadtree and directions of every detail subband (paper steps (3) to (8), (10)).

    ``coefficients`` holds the wavelet coefficients of every channel; they share one geometry.
    ``before(index, trees)``, if given, is called before subband ``index`` is read, with the
    trees of the coarser subbands (it may change the coefficients not read yet).
    """
    trees = []
    for index, (_, orientation, where) in enumerate(subband_slices(coefficients[0].shape, levels)):
        if before is not None:
            before(index, trees)
        subbands = np.stack([c[where] for c in coefficients])
        root = root_width(subbands.shape[1:])
        if transform == "wavelet" or root == 0:
            trees.append(flat_quadtree(subbands.shape[1:], root))
            continue
        covered = subbands[:, : subbands.shape[1] // root * root, : subbands.shape[2] // root * root]
        costs, dirs = [], []
        reference = reference_of(trees, index, orientation)
        width = MIN_WIDTH
        while width <= root:
            predicted = predicted_directions(
                reference, (covered.shape[1] // width, covered.shape[2] // width), width
            )
            hints = _children_directions(dirs[-1], width) if dirs else None
            cost, d = best_directions(
                covered, width, threshold, transform_1d=transform_1d, predicted=predicted, hints=hints
            )
            costs.append(cost)
            dirs.append(d)
            width *= 2
        trees.append(best_quadtree(costs, dirs, GEOMETRY_PRICE * LAMBDA * threshold * threshold))
    return trees


def _children_directions(children: np.ndarray, width: int) -> np.ndarray:
    """The directions of the four half-size squares of every square of ``width``, as indices
    at ``width`` (-1 for NULL): where the search of the larger square starts."""
    rows, cols = children.shape[0] // 2, children.shape[1] // 2
    quads = children.reshape(rows, 2, cols, 2).transpose(0, 2, 1, 3).reshape(rows, cols, 4)
    out = np.full(quads.shape, -1, np.int64)
    some = quads >= 0
    out[some] = nearest_direction(directions(width // 2)[0][quads[some]], width)
    return out


def forward(
    channel: np.ndarray,
    threshold: float,
    *,
    wavelet: Wavelet = DEFAULT_WAVELET,
    levels: int | None = None,
    transform: str = "bandelet",
    transform_1d: Transform1D = DEFAULT_TRANSFORM_1D,
) -> Bandelets:
    """Bandelet transform of one channel, with the basis chosen for threshold ``T``.

    Parameters
    ----------
    channel : ndarray, shape (H, W)
        Finite values.
    threshold : float
        ``T`` > 0: the quantization step the Lagrangian optimises the basis for.
    wavelet : str
        ``"cdf97"`` (biorthogonal, default) or an orthogonal wavelet of
        :data:`bandelets.format.header.WAVELETS`.
    levels : int, optional
        Wavelet levels (default :func:`bandelets.transform.wavelets.max_levels`).
    transform : {"bandelet", "wavelet"}
        ``"wavelet"`` keeps every square NULL.
    transform_1d : {"alpert2", "haar"}
        1D transform along the directions (:data:`bandelets.format.header.TRANSFORMS_1D`):
        Alpert's multiwavelet with two vanishing moments (default) or the paper's Haar.

    Returns
    -------
    Bandelets

    Examples
    --------
    >>> y, x = np.mgrid[0:64, 0:64] / 64
    >>> channel = np.tanh(20 * (x - 0.7 * y - 0.2))
    >>> b = forward(channel, threshold=0.05)
    >>> b.coefficients.shape, len(b.trees) == 3 * b.levels
    ((64, 64), True)
    >>> bool(np.allclose(inverse(b), channel))  # an orthonormal change of basis after the wavelets
    True
    """
    if np.ndim(channel) != 2:
        raise ValueError(f"forward takes one channel, an H x W array; got shape {np.shape(channel)}")
    x = check_image(channel, "image")[..., 0]
    check_options(transform, wavelet, transform_1d)
    check_threshold(threshold)
    levels = levels or max_levels(x.shape)
    c = wavedec(pad_channel(x, levels), wavelet, levels)
    trees = best_trees([c], levels, threshold, transform, transform_1d)
    return Bandelets(
        apply_trees(c, levels, trees, bandeletize, transform_1d),
        trees,
        x.shape,
        wavelet,
        levels,
        threshold,
        transform_1d,
    )
