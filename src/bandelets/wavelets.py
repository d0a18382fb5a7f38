"""Step (2) of the paper: the 2D wavelet transform of one channel.

Two families are offered:

* ``"cdf97"`` (default): the biorthogonal Cohen-Daubechies-Feauveau 9/7 wavelet of JPEG2000,
  computed by lifting with whole-sample symmetric extension, or with the "spherical"
  extension of Praun and Hoppe for octahedral geometry images (each edge glued to itself
  reversed). PyWavelets has this filter ("bior4.4") but its symmetric mode is not critically
  sampled (each level grows the subbands by the filter length), which would break the
  one-coefficient-per-pixel layout the bandelet quadtree needs; so this lifting is written here.
* any orthogonal Daubechies-family name PyWavelets knows (``"haar"``, ``"db2"``, ``"db4"``, ...),
  through :func:`pywt.wavedec2` with periodic extension, the only critically sampled
  extension under which these filters stay orthogonal.

Coefficients are returned in the Mallat layout: one ``(H, W)`` array whose top-left
``H / 2**levels x W / 2**levels`` block is the approximation and where the detail subbands
of level ``j`` (1 = finest) sit at ``[0:h, w:2w]`` (H), ``[h:2h, 0:w]`` (V) and ``[h:2h, w:2w]`` (D),
with ``h, w = H / 2**j, W / 2**j``.

Every subband is finally multiplied by the norm of its synthesis functions, so that an
error of ``e`` on any coefficient costs about ``e**2`` in the image for the biorthogonal
wavelet too. The Lagrangian of the bandelet search can then work on coefficients alone.
"""

from __future__ import annotations

import math
import warnings
from functools import cache

import numpy as np
import pywt

from .bitstream import DEFAULT_WAVELET, EXTENSIONS, MAX_LEVELS, WAVELETS

__all__ = [
    "check_extension",
    "subband_norms",
    "subband_slices",
    "wavedec",
    "waverec",
    "max_levels",
    "padded_shape",
]

# Lifting factorisation of the CDF 9/7 filter pair (Daubechies and Sweldens 1998).
_ALPHA = -1.586134342059924
_BETA = -0.052980118572961
_GAMMA = 0.882911075530934
_DELTA = 0.443506852043971
_ZETA = 1.230174104914001


def padded_shape(shape: tuple[int, int], levels: int) -> tuple[int, int]:
    """Size of a channel once padded to a multiple of ``2**levels`` on both sides."""
    step = 1 << levels
    return tuple(-(-side // step) * step for side in shape)


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


def _symmetric(s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whole-sample symmetric extension: ``s[n]`` past the end is ``s[n-1]``, ``d[-1]`` is ``d[0]``."""
    return s[..., -1:], d[..., :1]


def _lift_forward(x: np.ndarray, extend=_symmetric) -> tuple[np.ndarray, np.ndarray]:
    """One level of CDF 9/7 analysis along the last axis (even length).

    ``extend(s, d)`` gives the sample of ``s`` past its end and the one of ``d`` before its
    start, shape ``(..., 1)``; each reads only the channel it extends, so that every lifting
    step stays exactly invertible.
    """
    s = x[..., 0::2].copy()
    d = x[..., 1::2].copy()
    d += _ALPHA * (s + np.concatenate([s[..., 1:], extend(s, d)[0]], axis=-1))
    s += _BETA * (d + np.concatenate([extend(s, d)[1], d[..., :-1]], axis=-1))
    d += _GAMMA * (s + np.concatenate([s[..., 1:], extend(s, d)[0]], axis=-1))
    s += _DELTA * (d + np.concatenate([extend(s, d)[1], d[..., :-1]], axis=-1))
    return s * _ZETA, d / _ZETA


def _lift_inverse(s: np.ndarray, d: np.ndarray, extend=_symmetric) -> np.ndarray:
    """Exact inverse of :func:`_lift_forward` (with the same ``extend``)."""
    s = s / _ZETA
    d = d * _ZETA
    s -= _DELTA * (d + np.concatenate([extend(s, d)[1], d[..., :-1]], axis=-1))
    d -= _GAMMA * (s + np.concatenate([s[..., 1:], extend(s, d)[0]], axis=-1))
    s -= _BETA * (d + np.concatenate([extend(s, d)[1], d[..., :-1]], axis=-1))
    d -= _ALPHA * (s + np.concatenate([s[..., 1:], extend(s, d)[0]], axis=-1))
    x = np.empty(s.shape[:-1] + (2 * s.shape[-1],))
    x[..., 0::2] = s
    x[..., 1::2] = d
    return x


def _spherical(side: int, spacing: int, lines: list[tuple[int, int, int]]):
    """The extension of one lifting pass over a level of an octahedral geometry image.

    The image (``side`` x ``side`` pixels, centres at integer positions) is glued across each
    edge to itself turned by half a turn about the edge's midpoint: the sample ``k`` pixels
    beyond an edge is the one ``k - 1`` inside it, at the mirrored place along the edge. At a
    level whose samples lie ``spacing`` pixels apart along the lifting axis, the sample a
    lifting step needs past the end (``s`` at pixel ``side``) or before the start (``d`` at
    pixel ``-spacing``) is interpolated linearly between the channel's last (first) sample and
    the fold of that sample, which lies ``2 spacing - 1`` (``1``) pixels beyond the edge; at the
    finest level it is extrapolated from the folds of the last (first) two samples instead.
    The fold belongs to the line mirrored along the edge (pixel ``side - 1 - p`` for a line at
    pixel ``p``); ``lines`` lists the lines (the first axis) as runs ``(first pixel, spacing,
    count)``, and each line reads its mirror by linear interpolation within its own run.
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
    first, second = np.concatenate(first), np.concatenate(second)
    weight = np.concatenate(weight)[:, None]
    h = spacing

    def folded(v: np.ndarray) -> np.ndarray:
        return (1.0 - weight) * v[first] + weight * v[second]

    def extend(s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if h == 1 and s.shape[1] > 1:
            # The finest level continues the fold's far side from its two nearest samples
            # (at 1 and 3 pixels): the octahedral map has a kink across the edge, which
            # interpolating over the edge would carry into the details.
            after = 1.5 * folded(s[:, -1:]) - 0.5 * folded(s[:, -2:-1])
            before = 1.5 * folded(d[:, :1]) - 0.5 * folded(d[:, 1:2])
            return after, before
        # Coarser levels interpolate over the edge, with convex weights: extrapolating there
        # amplifies the quantization error at the border and loses on meshes.
        after = ((2 * h - 1) * s[:, -1:] + 2 * h * folded(s[:, -1:])) / (4 * h - 1)
        before = (d[:, :1] + 2 * h * folded(d[:, :1])) / (2 * h + 1)
        return after, before

    return extend


def _extensions(shape: tuple[int, int], level: int, extension: str):
    """Extensions of the row pass and of the column pass of ``level`` (1 = finest)."""
    if extension == "symmetric":
        return _symmetric, _symmetric
    side, h = shape[0], 1 << (level - 1)
    m = side // h
    # Row pass: the rows of the level's approximation, pixels 0, h, 2h, ... Column pass: the
    # columns of its low half (pixels 0, 2h, ...), then of its high half (h, 3h, ...).
    return _spherical(side, h, [(0, h, m)]), _spherical(side, h, [(0, 2 * h, m // 2), (h, 2 * h, m // 2)])


def _cdf97_dec(x: np.ndarray, levels: int, extension: str = "symmetric") -> np.ndarray:
    out = np.array(x, dtype=np.float64, copy=True)
    h, w = out.shape
    for level in range(1, levels + 1):
        rows, cols = _extensions(out.shape, level, extension)
        block = out[:h, :w]
        lo, hi = _lift_forward(block, rows)  # along rows: columns split
        block = np.concatenate([lo, hi], axis=1)
        lo, hi = _lift_forward(block.T, cols)  # along columns: rows split
        out[:h, :w] = np.concatenate([lo, hi], axis=1).T
        h, w = h // 2, w // 2
    return out


def _cdf97_rec(c: np.ndarray, levels: int, extension: str = "symmetric") -> np.ndarray:
    out = np.array(c, dtype=np.float64, copy=True)
    height, width = out.shape
    for level in range(levels, 0, -1):
        rows, cols = _extensions(out.shape, level, extension)
        h, w = height >> (level - 1), width >> (level - 1)
        block = out[:h, :w].T
        block = _lift_inverse(block[:, : h // 2], block[:, h // 2 :], cols).T
        out[:h, :w] = _lift_inverse(block[:, : w // 2], block[:, w // 2 :], rows)
    return out


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


def _raw_dec(x: np.ndarray, wavelet: str, levels: int, extension: str) -> np.ndarray:
    return _cdf97_dec(x, levels, extension) if wavelet == "cdf97" else _pywt_dec(x, wavelet, levels)


def _raw_rec(c: np.ndarray, wavelet: str, levels: int, extension: str) -> np.ndarray:
    return _cdf97_rec(c, levels, extension) if wavelet == "cdf97" else _pywt_rec(c, wavelet, levels)


def check_extension(shape: tuple[int, int], wavelet: str, levels: int, extension: str) -> None:
    """``ValueError`` unless ``extension`` applies to a ``shape`` channel at ``levels``."""
    if extension not in EXTENSIONS:
        raise ValueError(f"unknown extension {extension!r}; choose one of {', '.join(EXTENSIONS)}")
    if extension == "spherical" and (wavelet != "cdf97" or shape[0] != shape[1] or shape[0] % (1 << levels)):
        raise ValueError(
            f"the spherical extension needs the cdf97 wavelet and a square image whose side is a "
            f"multiple of {1 << levels}, got {wavelet} and {shape[1]} x {shape[0]}"
        )


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
            x = np.zeros(size)
            x[offset + (size >> (level + 1))] = 1.0
            for k in range(level, 0, -1):
                n = size >> (k - 1)
                x[:n] = _lift_inverse(x[: n // 2].copy(), x[n // 2 : n].copy())
            out[level] = math.sqrt(math.fsum(x * x))  # not BLAS: the same bits on every CPU
    return scaling, wavelet


def subband_norms(wavelet: str, levels: int) -> tuple[float, ...]:
    """Norm of the synthesis function of the approximation and of each detail subband.

    Orthogonal wavelets give 1. The CDF 9/7 functions are separable products of 1D scaling
    and wavelet functions, whose norms multiply.
    """
    if wavelet != "cdf97":
        return (1.0,) * (1 + 3 * levels)
    scaling, detail = _synthesis_norms_1d(levels)
    norms = [scaling[levels] ** 2]
    for level in range(levels, 0, -1):
        # H: low along the rows, high along the columns; V: the transpose; D: high twice.
        norms += [scaling[level] * detail[level]] * 2 + [detail[level] ** 2]
    return tuple(float(n) for n in norms)


def _norm_map(shape: tuple[int, int], wavelet: str, levels: int) -> np.ndarray:
    norms = subband_norms(wavelet, levels)
    scale = np.empty(shape)
    h, w = shape[0] >> levels, shape[1] >> levels
    scale[:h, :w] = norms[0]
    for norm, (*_, where) in zip(norms[1:], subband_slices(shape, levels), strict=True):
        scale[where] = norm
    return scale


def wavedec(
    x: np.ndarray, wavelet: str = DEFAULT_WAVELET, levels: int = 1, extension: str = "symmetric"
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
        as an octahedral geometry image (:func:`_spherical`; square, side a multiple of
        ``2**levels``; ``cdf97`` only: the orthogonal wavelets are periodic).

    Returns
    -------
    ndarray, shape (H, W), float64
        Coefficients in the Mallat layout, each subband scaled by the norm of its synthesis
        functions (so unit-norm synthesis functions, and ``waverec`` undoes it exactly).
    """
    if wavelet not in WAVELETS:
        raise ValueError(f"unknown wavelet {wavelet!r}; choose one of {', '.join(WAVELETS)}")
    check_extension(x.shape, wavelet, levels, extension)
    return _raw_dec(x, wavelet, levels, extension) * _norm_map(x.shape, wavelet, levels)


def waverec(
    c: np.ndarray, wavelet: str = DEFAULT_WAVELET, levels: int = 1, extension: str = "symmetric"
) -> np.ndarray:
    """Inverse of :func:`wavedec`: ``(H, W)`` coefficients to an ``(H, W)`` channel."""
    check_extension(c.shape, wavelet, levels, extension)
    return _raw_rec(c / _norm_map(c.shape, wavelet, levels), wavelet, levels, extension)
