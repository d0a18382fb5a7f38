"""Step (2) of the paper: the 2D wavelet transform of one channel.

Two families are offered:

* ``"cdf97"`` (default): the biorthogonal Cohen-Daubechies-Feauveau 9/7 wavelet of JPEG2000,
  computed by lifting with whole-sample symmetric extension, or with the "spherical"
  extension of Praun and Hoppe for octahedral geometry images (each edge glued to itself
  reversed). PyWavelets has this filter ("bior4.4") but its symmetric mode is not critically
  sampled (each level grows the subbands by the filter length), which would break the
  one-coefficient-per-pixel layout the bandelet quadtree needs; so this lifting is written here
  (compiled passes in :mod:`bandelets.transform.lifting`).
* any orthogonal Daubechies-family name PyWavelets knows (``"haar"``, ``"db2"``, ``"db4"``, ...),
  with periodic extension, the only critically sampled extension under which these filters
  stay orthogonal: through :func:`pywt.wavedec2`, except Haar, lifted by
  :mod:`bandelets.transform.lifting` (the same coefficients to the last bit, without PyWavelets' cost
  per call).
* ``"rbio1.3"``, lifted by :mod:`bandelets.transform.lifting` with symmetric extension (PyWavelets'
  reverse biorthogonal 1.3 away from the border): a biorthogonal wavelet whose analysis low-pass is the
  box average of a pair (as Haar's) and whose synthesis low-pass is smoother, so that the
  approximation of ``k`` levels is the ``2**k x 2**k`` box mip of the channel (``encode(box_mips=True)``,
  :mod:`bandelets.codec.boxlevels`). Its synthesis functions' norms are within 5 % of 1 and are taken
  as 1.

Coefficients are returned in the Mallat layout: one ``(H, W)`` array whose top-left
``H / 2**levels x W / 2**levels`` block is the approximation and where the detail subbands
of level ``j`` (1 = finest) sit at ``[0:h, w:2w]`` (H), ``[h:2h, 0:w]`` (V) and ``[h:2h, w:2w]`` (D),
with ``h, w = H / 2**j, W / 2**j``.

Every subband is finally multiplied by the norm of its synthesis functions, so that an
error of ``e`` on any coefficient costs about ``e**2`` in the image for the biorthogonal
wavelet too (the finest level's by :data:`FINEST_WEIGHT` more). The Lagrangian of the
bandelet search can then work on coefficients alone.
"""

from __future__ import annotations

import math
import warnings
from functools import cache

import numpy as np
import pywt

from ..format.fields import DEFAULT_WAVELET, EXTENSIONS, MAX_LEVELS, WAVELETS
from . import lifting

__all__ = [
    "check_extension",
    "coarse_blocks",
    "spherical_folds",
    "subband_norms",
    "subband_slices",
    "wavedec",
    "waverec",
    "max_levels",
]


def max_levels(shape: tuple[int, int]) -> int:
    """Default number of wavelet levels for an image of ``shape``.

    The coarsest approximation keeps at least 8 samples on its shorter side, and at most
    six levels are used: finer levels hold almost all of the coefficients and coarser
    ones gain nothing measurable.
    """
    smallest = min(shape)
    levels = 0
    while levels < MAX_LEVELS and smallest >= 16 * 2**levels:
        levels += 1
    return max(levels, 1)


def subband_slices(shape: tuple[int, int], levels: int) -> list[tuple[int, int, tuple]]:
    """Where each detail subband lives in the Mallat layout.

    Returns ``(level, orientation, (rows, cols))`` for every detail subband, coarsest level
    first and orientations H, V, D (0, 1, 2) within a level: the order in which the codec
    visits them.
    """
    height, width = shape
    out = []
    for level in range(levels, 0, -1):
        h, w = height >> level, width >> level
        out.append((level, 0, (slice(0, h), slice(w, 2 * w))))
        out.append((level, 1, (slice(h, 2 * h), slice(0, w))))
        out.append((level, 2, (slice(h, 2 * h), slice(w, 2 * w))))
    return out


@cache
def spherical_folds(side: int, lines: tuple[tuple[int, int, int], ...]) -> tuple[np.ndarray, ...]:
    """The mirror of every line of a lifting pass over a level of an octahedral geometry image.

    The image (``side`` x ``side`` pixels, centres at integer positions) is glued across each
    edge to itself turned by half a turn about the edge's midpoint: the sample ``k`` pixels
    beyond an edge is the one ``k - 1`` inside it, at the mirrored place along the edge. At a
    level whose samples lie ``h`` pixels apart along the lifting axis, the sample a lifting step
    needs past the end (``s`` at pixel ``side``) or before the start (``d`` at pixel ``-h``) is
    interpolated linearly between the line's last (first) sample and the fold of that sample,
    which lies ``2 h - 1`` (``1``) pixels beyond the edge; at the finest level it is
    extrapolated from the folds of the last (first) two samples instead (the octahedral map
    has a kink across the edge, which interpolating over the edge would carry into the
    details); coarser levels interpolate with convex weights (extrapolating there amplifies
    the quantization error at the border and loses on meshes). :mod:`bandelets.transform.lifting` does
    that arithmetic.

    The fold belongs to the line mirrored along the edge (pixel ``side - 1 - p`` for a line at
    pixel ``p``); ``lines`` lists the lines (the first axis) as runs ``(first pixel, spacing,
    count)``, and each line reads its mirror by linear interpolation within its own run.

    Returns
    -------
    first, second : ndarray of int64, shape (lines,)
    weight : ndarray of float64, shape (lines,)
        The mirror of line ``i`` is ``(1 - weight[i])`` line ``first[i]`` plus ``weight[i]``
        line ``second[i]``.
    """
    first, second, weight = [], [], []
    start = 0
    for offset, step, count in lines:
        mirror = side - 1 - 2 * offset - step * np.arange(count)  # pixels past the run's start
        low = np.clip(mirror // step, 0, count - 1)
        first.append(start + low)
        second.append(start + np.clip(mirror // step + 1, 0, count - 1))
        weight.append((mirror - step * low).clip(0, step) / step)
        start += count
    return np.concatenate(first), np.concatenate(second), np.concatenate(weight).astype(np.float64)


def _folds(shape: tuple[int, int], level: int, extension: str):
    """The folds of the row pass and of the column pass of ``level`` (1 = finest), or Nones."""
    if extension == "symmetric":
        return None, None
    side, h = shape[0], 1 << (level - 1)
    m = side // h
    # Row pass: the rows of the level's approximation, pixels 0, h, 2h, ... Column pass: the
    # columns of its low half (pixels 0, 2h, ...), then of its high half (h, 3h, ...).
    return spherical_folds(side, ((0, h, m),)), spherical_folds(
        side, ((0, 2 * h, m // 2), (h, 2 * h, m // 2))
    )


def _lifting_dec(out: np.ndarray, wavelet: str, levels: int, extension: str = "symmetric") -> np.ndarray:
    """Raw (unnormalised) transform by :mod:`bandelets.transform.lifting`, in place on ``out`` (float64,
    row-major), which it returns: each level a row pass into a work array, then a column pass back."""
    work = np.empty_like(out)
    h, w = out.shape
    for level in range(1, levels + 1):
        block, scratch = out[:h, :w], work[:h, :w]
        if wavelet == "haar":  # columns first, as PyWavelets
            lifting.haar_pass(block.T, scratch.T, True)
            lifting.haar_pass(scratch, block, True)
            _swap_haar_details(block)
        elif wavelet == "rbio1.3":
            lifting.rbio13_pass(block, scratch, True)
            lifting.rbio13_pass(scratch.T, block.T, True)
        else:
            rows, cols = _folds(out.shape, level, extension)
            lifting.cdf97_pass(block, scratch, True, rows, 1 << (level - 1))
            lifting.cdf97_pass(scratch.T, block.T, True, cols, 1 << (level - 1))
        h, w = h // 2, w // 2
    return out


def _lifting_rec(out: np.ndarray, wavelet: str, levels: int, extension: str = "symmetric") -> np.ndarray:
    """Inverse of :func:`_lifting_dec`, in place on ``out`` (float64, row-major), which it returns."""
    work = np.empty_like(out)
    height, width = out.shape
    for level in range(levels, 0, -1):
        h, w = height >> (level - 1), width >> (level - 1)
        block, scratch = out[:h, :w], work[:h, :w]
        if wavelet == "haar":
            _swap_haar_details(block)
            lifting.haar_pass(block, scratch, False)
            lifting.haar_pass(scratch.T, block.T, False)
        elif wavelet == "rbio1.3":
            lifting.rbio13_pass(block.T, scratch.T, False)
            lifting.rbio13_pass(scratch, block, False)
        else:
            rows, cols = _folds(out.shape, level, extension)
            lifting.cdf97_pass(block.T, scratch.T, False, cols, 1 << (level - 1))
            lifting.cdf97_pass(scratch, block, False, rows, 1 << (level - 1))
    return out


def _swap_haar_details(block: np.ndarray) -> None:
    """Swap the two mixed subbands of a level, in place: PyWavelets, which coded Haar before the
    lifting, stores the details along the columns in the H place, the transpose of CDF 9/7's."""
    h, w = block.shape[0] // 2, block.shape[1] // 2
    top = block[:h, w:].copy()
    block[:h, w:] = block[h:, :w]
    block[h:, :w] = top


def _pywt_dec(x: np.ndarray, wavelet: str, levels: int) -> np.ndarray:
    with warnings.catch_warnings():
        # PyWavelets warns when the coarsest subband is shorter than a long filter (db6, db8);
        # with periodic extension the transform stays orthogonal and exact, so it is harmless.
        warnings.simplefilter("ignore", UserWarning)
        coeffs = pywt.wavedec2(x, wavelet, mode="periodization", level=levels)
    out = np.empty(x.shape)
    a = coeffs[0]
    out[: a.shape[0], : a.shape[1]] = a
    for (_, _, where), band in zip(
        subband_slices(x.shape, levels), (b for triple in coeffs[1:] for b in triple), strict=True
    ):
        out[where] = band
    return out


def _pywt_rec(c: np.ndarray, wavelet: str, levels: int) -> np.ndarray:
    h, w = c.shape[0] >> levels, c.shape[1] >> levels
    coeffs: list = [c[:h, :w]]
    slices = subband_slices(c.shape, levels)
    for i in range(levels):
        coeffs.append(tuple(c[slices[3 * i + k][2]] for k in range(3)))
    return pywt.waverec2(coeffs, wavelet, mode="periodization")


#: Wavelets lifted by :mod:`bandelets.transform.lifting`; the others go through PyWavelets.
_LIFTED = ("cdf97", "haar", "rbio1.3")


def _raw_dec(x: np.ndarray, wavelet: str, levels: int, extension: str) -> np.ndarray:
    """The raw coefficients of the channel ``x`` (float64, row-major), written over it."""
    if wavelet in _LIFTED:
        return _lifting_dec(x, wavelet, levels, extension)
    x[...] = _pywt_dec(x, wavelet, levels)
    return x


def _raw_rec(c: np.ndarray, wavelet: str, levels: int, extension: str) -> np.ndarray:
    """The channel of the raw coefficients ``c`` (float64, row-major), written over them."""
    if wavelet in _LIFTED:
        return _lifting_rec(c, wavelet, levels, extension)
    c[...] = _pywt_rec(c, wavelet, levels)
    return c


def check_extension(shape: tuple[int, int], wavelet: str, levels: int, extension: str) -> None:
    """``ValueError`` unless ``extension`` applies to a ``shape`` channel at ``levels``."""
    if extension not in EXTENSIONS:
        raise ValueError(f"unknown extension {extension!r}; choose one of {', '.join(EXTENSIONS)}")
    if extension == "spherical" and (wavelet != "cdf97" or shape[0] != shape[1] or shape[0] % (1 << levels)):
        raise ValueError(
            f"the spherical extension needs the cdf97 wavelet and a square image whose side is a "
            f"multiple of {1 << levels}, got {wavelet} and {shape[1]} x {shape[0]}"
        )


#: Factor on the finest level's norms (CDF 9/7): its step is ``T / FINEST_WEIGHT``, finer than the
#: coarser levels' (format version 12). The exact norms weigh every level's error alike, but the
#: quantizer is not the high-rate one they assume: 10/9 gained +0.03 to +0.06 dB BD-PSNR on the
#: crease map at 256 and the bevel map at 256 and 512 (-0.01 on the bumps); the other way round
#: lost (the coarser levels at 1.15 to 1.4 times their norm, a finer step there: -0.05 to -0.24
#: dB on the bevel map at 256). BENCHMARKS, "A step per wavelet level".
FINEST_WEIGHT = 10.0 / 9.0


@cache
def _synthesis_norms_1d(levels: int) -> tuple[np.ndarray, np.ndarray]:
    """Norms of the 1D CDF 9/7 synthesis functions: scaling and wavelet, levels 1..``levels``.

    Measured by reconstructing a unit impulse in the middle of each band of a signal long
    enough that the boundary does not reach it.
    """
    size = 2 ** (levels + 5)
    scaling, wavelet = np.empty(levels + 1), np.empty(levels + 1)
    for level in range(1, levels + 1):
        for out, offset in ((scaling, 0), (wavelet, size >> level)):
            x = np.zeros((1, size))
            x[0, offset + (size >> (level + 1))] = 1.0
            work = np.empty_like(x)
            for k in range(level, 0, -1):
                n = size >> (k - 1)
                lifting.cdf97_pass(x[:, :n], work[:, :n], False)
                x[:, :n] = work[:, :n]
            out[level] = math.sqrt(math.fsum(x.ravel() * x.ravel()))  # not BLAS: the same bits on every CPU
    return scaling, wavelet


def subband_norms(wavelet: str, levels: int) -> tuple[float, ...]:
    """Norm of the synthesis function of the approximation and of each detail subband, the
    finest level's weighted by :data:`FINEST_WEIGHT` (CDF 9/7).

    Orthogonal wavelets give 1. The CDF 9/7 functions are separable products of 1D scaling
    and wavelet functions, whose norms multiply.
    """
    if wavelet != "cdf97":
        return (1.0,) * (1 + 3 * levels)
    scaling, detail = _synthesis_norms_1d(levels)
    norms = [scaling[levels] ** 2]
    for level in range(levels, 0, -1):
        # H: low along the rows, high along the columns; V: the transpose; D: high twice.
        weight = FINEST_WEIGHT if level == 1 else 1.0
        norms += [weight * scaling[level] * detail[level]] * 2 + [weight * detail[level] ** 2]
    return tuple(float(n) for n in norms)


def _normalise(c: np.ndarray, wavelet: str, levels: int, inverse: bool = False) -> np.ndarray:
    """Every subband of ``c`` multiplied (``inverse``: divided) by its norm, in place."""
    if wavelet == "cdf97":
        lifting.scale_subbands(c, levels, np.array(subband_norms(wavelet, levels)), inverse)
    return c


def wavedec(
    x: np.ndarray,
    wavelet: str = DEFAULT_WAVELET,
    levels: int = 1,
    extension: str = "symmetric",
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Normalised 2D wavelet transform of one channel.

    Parameters
    ----------
    x : ndarray, shape (H, W)
        One channel; ``H`` and ``W`` must be multiples of ``2**levels``.
    wavelet : str
        One of :data:`WAVELETS`.
    levels : int
        Number of decomposition levels.
    extension : {"symmetric", "spherical"}
        How ``cdf97`` extends the channel past its border: whole-sample symmetric, or glued
        as an octahedral geometry image (:func:`spherical_folds`; square, side a multiple of
        ``2**levels``; ``cdf97`` only: the orthogonal wavelets are periodic).
    out : ndarray, shape (H, W), float64, row-major, optional
        Where to write the coefficients (``x`` itself for a transform in place).

    Returns
    -------
    ndarray, shape (H, W), float64
        Coefficients in the Mallat layout, each subband scaled by the norm of its synthesis
        functions (so unit-norm synthesis functions, and ``waverec`` undoes it exactly).
    """
    if wavelet not in WAVELETS:
        raise ValueError(f"unknown wavelet {wavelet!r}; choose one of {', '.join(WAVELETS)}")
    check_extension(x.shape, wavelet, levels, extension)
    return _normalise(_raw_dec(_working_copy(x, out), wavelet, levels, extension), wavelet, levels)


def waverec(
    c: np.ndarray,
    wavelet: str = DEFAULT_WAVELET,
    levels: int = 1,
    extension: str = "symmetric",
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Inverse of :func:`wavedec`: ``(H, W)`` coefficients to an ``(H, W)`` channel (written into
    ``out`` if given, which may be ``c`` itself)."""
    check_extension(c.shape, wavelet, levels, extension)
    c = _normalise(_working_copy(c, out), wavelet, levels, inverse=True)
    return _raw_rec(c, wavelet, levels, extension)


def coarse_blocks(c: np.ndarray, levels: int, first: int) -> dict[int, np.ndarray]:
    """The coarse part of a channel at every count of levels, from its CDF 9/7 coefficients.

    Parameters
    ----------
    c : ndarray, shape (H, W)
        ``wavedec(x, "cdf97", levels)`` of a channel ``x`` (symmetric extension).
    levels : int
    first : int
        From 1 to ``levels``.

    Returns
    -------
    dict
        ``L -> wavedec(x, "cdf97", L)[:H >> first, :W >> first]`` for ``L`` from ``first`` to
        ``levels`` (the approximation of ``first`` levels, split ``L - first`` times more),
        made from that block alone: the channel is not transformed again.
    """
    h, w = c.shape[0] >> first, c.shape[1] >> first

    def scale(block: np.ndarray, total: int, inverse: bool) -> np.ndarray:
        norms = np.array(subband_norms("cdf97", total)[: 1 + 3 * (total - first)])
        if total == first:  # the approximation alone
            return block / norms[0] if inverse else block * norms[0]
        lifting.scale_subbands(block, total - first, norms, inverse)
        return block

    raw = _raw_rec(
        scale(np.array(c[:h, :w], np.float64, order="C"), levels, True), "cdf97", levels - first, "symmetric"
    )
    out = {}
    for total in range(first, levels + 1):
        block = _raw_dec(raw.copy(), "cdf97", total - first, "symmetric")
        out[total] = scale(block, total, False)
    return out


def _working_copy(x: np.ndarray, out: np.ndarray | None) -> np.ndarray:
    """``x`` copied into ``out`` (float64 row-major), or into a new array."""
    if out is None:
        return np.array(x, dtype=np.float64, order="C")
    if out.shape != x.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
        raise ValueError(f"out must be a row-major float64 array of shape {x.shape}")
    if out is not x:
        out[...] = x
    return out
