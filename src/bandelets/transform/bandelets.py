"""The paper's bandelet transform of one channel for given quadtrees, and its pieces the codec reuses.

A :class:`Bandelets` holds the coefficients of one channel in the basis of its quadtrees (one per
detail subband): :func:`inverse` undoes the bandeletization of every square
(:mod:`bandelets.transform.bandeletize`) and the wavelet transform. :func:`apply_trees` applies the
bandeletization (or its inverse) on coefficients already wavelet-transformed, shared by the encoder
and the decoder. The choice of the quadtrees is the encoder's search:
:func:`bandelets.search.basis.forward`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..format.fields import DEFAULT_TRANSFORM_1D, padded_shape
from ..runtime.threads import each, spare_core
from .bandeletize import debandeletize
from .wavelets import subband_slices, wavedec, waverec

__all__ = [
    "Bandelets",
    "inverse",
    "apply_trees",
    "pad_channel",
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


def pad_channel(channel: np.ndarray, levels: int) -> np.ndarray:
    rows, cols = padded_shape(channel.shape, levels)
    # Mirror padding keeps the padded image as smooth as the original at its border.
    return np.pad(channel, ((0, rows - channel.shape[0]), (0, cols - channel.shape[1])), mode="symmetric")


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


def inverse(b: Bandelets) -> np.ndarray:
    """Inverse bandelet transform: the channel, shape ``b.shape`` (see :func:`forward`)."""
    c = apply_trees(b.coefficients, b.levels, b.trees, debandeletize, b.transform_1d)
    return waverec(c, b.wavelet, b.levels)[: b.shape[0], : b.shape[1]]


def padded_channels(x: np.ndarray, levels: int) -> list[np.ndarray]:
    """Every channel of ``x`` (H, W, C), padded to a multiple of ``2**levels`` on both sides."""
    return [pad_channel(x[..., k], levels) for k in range(x.shape[2])]


#: Pixels from which :func:`wavelet_coefficients` transforms the channels in threads (at 512 x 512 the
#: hand-over cost more than it saved, measured on the directional analysis).
CHANNELS_IN_THREADS_FROM = 1024 * 1024


def wavelet_coefficients(
    x: np.ndarray, wavelet: str, levels: int, extension: str = "symmetric"
) -> list[np.ndarray]:
    """Padded, normalised wavelet coefficients of every channel of ``x`` (H, W, C); the channels in
    threads from :data:`CHANNELS_IN_THREADS_FROM` pixels (:func:`bandelets.runtime.threads.each`)."""
    # Not in a tile's thread either, which shares the cores with the other tile in flight.
    threaded = x.shape[0] * x.shape[1] >= CHANNELS_IN_THREADS_FROM and spare_core()
    return each(lambda c: wavedec(c, wavelet, levels, extension), padded_channels(x, levels), threaded)
