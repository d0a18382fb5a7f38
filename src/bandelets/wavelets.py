"""Step (2) of the paper: the 2D wavelet transform of one channel.

Two families are offered:

* ``"cdf97"`` (default): the biorthogonal Cohen-Daubechies-Feauveau 9/7 wavelet of JPEG2000,
  computed by lifting with whole-sample symmetric extension. PyWavelets has this filter
  ("bior4.4") but its symmetric mode is not critically sampled (each level grows the
  subbands by the filter length), which would break the one-coefficient-per-pixel layout
  the bandelet quadtree needs; so this lifting is written here.
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

import warnings
from functools import cache

import numpy as np
import pywt

__all__ = [
    "WAVELETS",
    "subband_slices",
    "wavedec",
    "waverec",
    "max_levels",
    "MAX_LEVELS",
    "padded_shape",
]

#: Wavelets that can be stored in a .bdl header, by code. Append only: the code is the format.
WAVELETS = ("cdf97", "haar", "db2", "db4", "db6", "db8")

# Lifting factorisation of the CDF 9/7 filter pair (Daubechies and Sweldens 1998).
_ALPHA = -1.586134342059924
_BETA = -0.052980118572961
_GAMMA = 0.882911075530934
_DELTA = 0.443506852043971
_ZETA = 1.230174104914001


#: Most decomposition levels the format stores.
MAX_LEVELS = 6


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


def _lift_forward(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One level of CDF 9/7 analysis along the last axis (even length)."""
    s = x[..., 0::2].copy()
    d = x[..., 1::2].copy()
    # Whole-sample symmetric extension: s[n+1] past the end is s[n], d[-1] is d[0].
    d += _ALPHA * (s + np.concatenate([s[..., 1:], s[..., -1:]], axis=-1))
    s += _BETA * (d + np.concatenate([d[..., :1], d[..., :-1]], axis=-1))
    d += _GAMMA * (s + np.concatenate([s[..., 1:], s[..., -1:]], axis=-1))
    s += _DELTA * (d + np.concatenate([d[..., :1], d[..., :-1]], axis=-1))
    return s * _ZETA, d / _ZETA


def _lift_inverse(s: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Exact inverse of :func:`_lift_forward`."""
    s = s / _ZETA
    d = d * _ZETA
    s -= _DELTA * (d + np.concatenate([d[..., :1], d[..., :-1]], axis=-1))
    d -= _GAMMA * (s + np.concatenate([s[..., 1:], s[..., -1:]], axis=-1))
    s -= _BETA * (d + np.concatenate([d[..., :1], d[..., :-1]], axis=-1))
    d -= _ALPHA * (s + np.concatenate([s[..., 1:], s[..., -1:]], axis=-1))
    x = np.empty(s.shape[:-1] + (2 * s.shape[-1],))
    x[..., 0::2] = s
    x[..., 1::2] = d
    return x


def _cdf97_dec(x: np.ndarray, levels: int) -> np.ndarray:
    out = np.array(x, dtype=np.float64, copy=True)
    h, w = out.shape
    for _ in range(levels):
        block = out[:h, :w]
        lo, hi = _lift_forward(block)  # along rows: columns split
        block = np.concatenate([lo, hi], axis=1)
        lo, hi = _lift_forward(block.T)  # along columns: rows split
        out[:h, :w] = np.concatenate([lo, hi], axis=1).T
        h, w = h // 2, w // 2
    return out


def _cdf97_rec(c: np.ndarray, levels: int) -> np.ndarray:
    out = np.array(c, dtype=np.float64, copy=True)
    height, width = out.shape
    for level in range(levels, 0, -1):
        h, w = height >> (level - 1), width >> (level - 1)
        block = out[:h, :w].T
        block = _lift_inverse(block[:, : h // 2], block[:, h // 2 :]).T
        out[:h, :w] = _lift_inverse(block[:, : w // 2], block[:, w // 2 :])
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


def _raw_dec(x: np.ndarray, wavelet: str, levels: int) -> np.ndarray:
    return _cdf97_dec(x, levels) if wavelet == "cdf97" else _pywt_dec(x, wavelet, levels)


def _raw_rec(c: np.ndarray, wavelet: str, levels: int) -> np.ndarray:
    return _cdf97_rec(c, levels) if wavelet == "cdf97" else _pywt_rec(c, wavelet, levels)


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
            out[level] = np.linalg.norm(x)
    return scaling, wavelet


def _subband_norms(wavelet: str, levels: int) -> tuple[float, ...]:
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
    norms = _subband_norms(wavelet, levels)
    scale = np.empty(shape)
    h, w = shape[0] >> levels, shape[1] >> levels
    scale[:h, :w] = norms[0]
    for norm, (*_, where) in zip(norms[1:], subband_slices(shape, levels), strict=True):
        scale[where] = norm
    return scale


def wavedec(x: np.ndarray, wavelet: str = "cdf97", levels: int = 1) -> np.ndarray:
    """Normalised 2D wavelet transform of one channel.

    Parameters
    ----------
    x : ndarray, shape (H, W)
        One channel; ``H`` and ``W`` must be multiples of ``2**levels``.
    wavelet : str
        One of :data:`WAVELETS`.
    levels : int
        Number of decomposition levels.

    Returns
    -------
    ndarray, shape (H, W), float64
        Coefficients in the Mallat layout, each subband scaled by the norm of its synthesis
        functions (so unit-norm synthesis functions, and ``waverec`` undoes it exactly).
    """
    if wavelet not in WAVELETS:
        raise ValueError(f"unknown wavelet {wavelet!r}; choose one of {', '.join(WAVELETS)}")
    return _raw_dec(x, wavelet, levels) * _norm_map(x.shape, wavelet, levels)


def waverec(c: np.ndarray, wavelet: str = "cdf97", levels: int = 1) -> np.ndarray:
    """Inverse of :func:`wavedec`: ``(H, W)`` coefficients to an ``(H, W)`` channel."""
    return _raw_rec(c / _norm_map(c.shape, wavelet, levels), wavelet, levels)
