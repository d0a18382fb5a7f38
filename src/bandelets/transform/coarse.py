"""The coarse approximation of a channel at a wavelet level, from its coefficients: the image a
prefix of a file decodes to (format version 19, :mod:`bandelets.codec.levels`).

The inverse transform stops ``level`` levels early: the block of the coarse subbands is inverted as
:func:`bandelets.transform.wavelets.waverec` and
:func:`bandelets.transform.directional.transform` would invert it, then divided by the DC gain of
the ``level`` analysis levels left out, so that it holds the channel's local means (the low-pass of
the wavelet, a smoother mip than a box average).
"""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy import ndimage

from .directional import BLOCK, OFFSETS, SCALES, WEIGHTS
from .lifting import cdf97_pass, directional_pass, haar_pass, rbio13_pass
from .wavelets import _LIFTED, _folds, _normalise, _pywt_rec, _raw_dec, _raw_rec, _swap_haar_details

__all__ = ["box_filtered", "coarse"]


def coarse(
    c: np.ndarray,
    wavelet: str,
    levels: int,
    level: int,
    extension: str = "symmetric",
    lifting: int = 0,
    fields: list | None = None,
) -> np.ndarray:
    """The approximation at ``level`` (1 = half the size) of the channel of normalised coefficients ``c``.

    Parameters
    ----------
    c : ndarray, shape (H, W), float64, row-major
        The channel's coefficients (:func:`bandelets.transform.wavelets.wavedec`), overwritten; only
        the subbands coarser than ``level`` are read.
    wavelet, levels, extension
        Those of the transform.
    level : int
        From 0 to ``levels``.
    lifting, fields
        The finest levels lifted along directions and the directions of their passes
        (:func:`bandelets.transform.directional.transform`), if any.

    Returns
    -------
    ndarray, shape (H >> level, W >> level): the channel's local means.
    """
    _normalise(c, wavelet, levels, inverse=True)
    h, w = c.shape[0] >> level, c.shape[1] >> level
    if wavelet not in _LIFTED:
        block = c[:h, :w] if level == levels else _pywt_rec(c[:h, :w].copy(), wavelet, levels - level)
    else:
        _invert_to(c, wavelet, levels, level, extension, lifting, fields)
        block = c[:h, :w]
    return block / _gain(wavelet, level)


def _invert_to(c, wavelet, levels, level, extension, lifting, fields) -> None:
    """The inverse lifting of the levels coarser than ``level``, in place on ``c`` (raw coefficients):
    each level as :func:`bandelets.transform.wavelets._lifting_rec` or, lifted along directions, as
    :func:`bandelets.transform.directional.transform` inverts it."""
    work = np.empty_like(c)
    height, width = c.shape
    for lev in range(levels, level, -1):
        h, w = height >> (lev - 1), width >> (lev - 1)
        block, scratch = c[:h, :w], work[:h, :w]
        if lev <= lifting:  # the columns pass, then the rows pass (directional.transform, reversed)
            codes = [np.asarray(fields[2 * (lev - 1) + p], np.int64) for p in (0, 1)]
            directional_pass(c[:h, :w].T, work[:h, :w].T, False, codes[1], OFFSETS, WEIGHTS, SCALES, BLOCK)
            directional_pass(work[:h, :w], c[:h, :w], False, codes[0], OFFSETS, WEIGHTS, SCALES, BLOCK)
        elif wavelet == "haar":
            _swap_haar_details(block)
            haar_pass(block, scratch, False)
            haar_pass(scratch.T, block.T, False)
        elif wavelet == "rbio1.3":
            rbio13_pass(block.T, scratch.T, False)
            rbio13_pass(scratch, block, False)
        else:
            rows, cols = _folds(c.shape, lev, extension)
            cdf97_pass(block.T, scratch.T, False, cols, 1 << (lev - 1))
            cdf97_pass(scratch, block, False, rows, 1 << (lev - 1))


@cache
def _gain(wavelet: str, level: int) -> float:
    """The value the raw analysis of ``level`` levels gives a constant 1 in the approximation."""
    ones = np.ones((8 << level, 8 << level))
    return float(_raw_dec(ones, wavelet, level, "symmetric")[0, 0]) if level else 1.0


#: Taps of :func:`box_filtered` on either side of a sample (the support of the CDF 9/7 synthesis
#: scaling function at any level, in samples of that level, is within 4 on either side).
_REACH = 6


def box_filtered(a: np.ndarray, wavelet: str, level: int) -> np.ndarray:
    """The ``2**level x 2**level`` box averages of the image the approximation ``a`` (of
    :func:`coarse`) synthesises at full size with no detail: what a mip made from that image holds.

    The approximation is the low-pass of the wavelet, sharper than a box average: on the shared
    normal maps its mean angle from the box mip of the original is about twice that of this filtered
    one (issue 39). The filter is separable, the box average of the synthesis scaling function
    sampled at the level's grid (:func:`_box_taps`), with whole-sample symmetric extension.
    """
    if not level:
        return a
    taps = _box_taps(wavelet, level)
    out = ndimage.convolve1d(a, taps, axis=0, mode="mirror")
    return ndimage.convolve1d(out, taps, axis=1, mode="mirror")


@cache
def _box_taps(wavelet: str, level: int) -> np.ndarray:
    """The box average over ``2**level`` samples of the synthesis scaling function of ``level``, at
    offsets ``-_REACH`` to ``_REACH`` of the level's grid (a convolution kernel summing to 1)."""
    side = 16
    full = np.zeros((side << level, side << level))
    full[side // 2, side // 2] = 1.0  # scaled by taps.sum() below
    x = _raw_rec(full, wavelet, level, "symmetric")
    boxed = x.reshape(side, 1 << level, side, 1 << level).mean(axis=(1, 3)).sum(axis=0)
    taps = boxed[side // 2 - _REACH : side // 2 + _REACH + 1]
    return taps / taps.sum()
