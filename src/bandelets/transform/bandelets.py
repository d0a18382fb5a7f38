"""The paper's bandelet transform of one channel, and its pieces the codec reuses.

``forward`` and ``inverse`` are steps (1) to (10) of the paper: pad, 2D wavelet transform, then
in every detail subband the Lagrangian search of the best direction of every dyadic square
(:mod:`bandelets.search.lagrangian`), the best quadtree (:mod:`bandelets.transform.quadtree`), and the
bandeletization (:mod:`bandelets.transform.bandeletize`). :func:`best_trees` and :func:`apply_trees` are the
search and its application on coefficients already transformed, shared with the encoder and
the decoder.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..codec.options import check_image, check_options, check_threshold
from ..coding.trees import predicted_directions, reference_of
from ..format.header import DEFAULT_TRANSFORM_1D, DEFAULT_WAVELET, Transform1D, Wavelet
from ..search.lagrangian import GEOMETRY_PRICE, LAMBDA, best_directions
from .bandeletize import bandeletize, debandeletize
from .geometry import directions, nearest_direction
from .quadtree import MIN_WIDTH, best_quadtree, flat_quadtree, root_width
from .wavelets import max_levels, padded_shape, subband_slices, wavedec, waverec

__all__ = [
    "Bandelets",
    "forward",
    "inverse",
    "best_trees",
    "apply_trees",
    "padded_channels",
    "wavelet_coefficients",
]


@dataclass(frozen=True)
class Bandelets:
    """Bandelet representation of one channel.

    Attributes
    ----------
    coefficients : ndarray, shape (H', W'), float64
        Wavelet coefficients (Mallat layout, padded size) with every bandelet square replaced
        by its 1D coefficients in zig-zag order.
    trees : list of Quadtree
        Segmentation and directions of each detail subband, coarsest level first, H, V, D.
    shape : (H, W)
        Size of the channel before padding.
    wavelet : str
    levels : int
    threshold : float
        The ``T`` the basis was chosen for.
    transform_1d : str
        The 1D transform along the directions.
    """

    coefficients: np.ndarray
    trees: list
    shape: tuple
    wavelet: str
    levels: int
    threshold: float
    transform_1d: str = DEFAULT_TRANSFORM_1D


def _pad(channel: np.ndarray, levels: int) -> np.ndarray:
    rows, cols = padded_shape(channel.shape, levels)
    # Mirror padding keeps the padded image as smooth as the original at its border.
    return np.pad(channel, ((0, rows - channel.shape[0]), (0, cols - channel.shape[1])), mode="symmetric")


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


def apply_trees(
    coefficients: np.ndarray, levels: int, trees: list, transform_fn, transform_1d: str, inplace: bool = False
) -> np.ndarray:
    """A copy of the Mallat-layout ``coefficients`` (H', W') with ``transform_fn`` (:func:`bandeletize`
    or :func:`debandeletize`) applied to every detail subband with its tree; ``inplace``: the
    ``coefficients`` themselves, transformed."""
    out = coefficients if inplace else coefficients.copy()
    for (_, _, where), tree in zip(subband_slices(coefficients.shape, levels), trees, strict=True):
        if tree.squares:  # else every square is NULL: the wavelet coefficients stay
            transform_fn(out[where], tree, transform_1d, out=out[where])
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
    c = wavedec(_pad(x, levels), wavelet, levels)
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


def inverse(b: Bandelets) -> np.ndarray:
    """Inverse bandelet transform: the channel, shape ``b.shape`` (see :func:`forward`)."""
    c = apply_trees(b.coefficients, b.levels, b.trees, debandeletize, b.transform_1d)
    return waverec(c, b.wavelet, b.levels)[: b.shape[0], : b.shape[1]]


def padded_channels(x: np.ndarray, levels: int) -> list[np.ndarray]:
    """Every channel of ``x`` (H, W, C), padded to a multiple of ``2**levels`` on both sides."""
    return [_pad(x[..., k], levels) for k in range(x.shape[2])]


def wavelet_coefficients(
    x: np.ndarray, wavelet: str, levels: int, extension: str = "symmetric"
) -> list[np.ndarray]:
    """Padded, normalised wavelet coefficients of every channel of ``x`` (H, W, C)."""
    return [wavedec(channel, wavelet, levels, extension) for channel in padded_channels(x, levels)]
