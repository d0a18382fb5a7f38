"""The Riesz pair of a normal map's two channels: one height-like channel and what no height explains.

A tangent-space normal map baked from a height field ``h`` (bevelled shapes and lettering, bumps,
grooves) is its slope field: its two coded channels ``(a, b)`` (x and y, or their azimuthal
equidistant coordinates, :mod:`bandelets.codec.normalmaps`) are, up to a small residual, ``(h_x,
s h_y)`` (``s``: the orientation of the green axis against the rows, +1 or -1). Coding both
codes the same height twice. Per spatial frequency ``(u, v)`` the gradient of a cosine of ``h``
is a vector along ``(v, u)``; turning ``(a, b)`` at every frequency onto that direction and
its normal gives

* ``g``: the component along the gradients (``|omega| h`` for a map of slopes: a height seen
  through half a derivative), which holds all of a height field's energy, and
* ``g'``: the component across them (a curl), 0.08 to 0.3 % of the energy of the generated
  crease, bumps and bevel maps, 11 % of the lava flow's, 26 % of the acacia door's.

The rotation is orthonormal at every frequency (DCT-II of ``g`` and DST-II of ``g'`` in both
directions; DST-II x DCT-II of ``a`` and DCT-II x DST-II of ``b``: the half-sample symmetric
extension of ``h``, odd for its derivative across each side), so it keeps the squared error of
the channels: the coder codes ``(g, g')`` with its usual transform and quantizer, and the
decoder, its restoration and its loop filter see ``(a, b)`` again (:func:`inverse` ends the
synthesis of :func:`bandelets.codec.decoder.channel_transforms`). The frequencies that have only one
of ``a``, ``b`` (the zero and Nyquist rows and columns) are handed one to one to the free
coefficients of ``g`` and ``g'`` (the mean of ``g`` takes ``b``'s last one), which keeps the map
a bijection.

Why written here: scipy's DCT and DST do the transforms; no library pairs them into the
Helmholtz decomposition of a sampled slope field with an exact orthonormal inverse.

BENCHMARKS, "Where main stands: format version 15", measures where it pays (the encoder chooses it
per file: :func:`bandelets.codec.encoder.encode`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit
from scipy import fft

from ..runtime.threads import CORES

__all__ = ["forward", "inverse", "oriented", "precision", "SINGLE_FROM"]

#: The decoder turns the channels in float32 from this threshold on (3.5 times faster than in
#: float64 at 512 x 512): the rounding of the transforms, about 1e-6 on the channels' values (at
#: most a few units), is then below ``T / 2000``; below it, in float64.
SINGLE_FROM = 2.0**-9


@lru_cache(maxsize=8)
def _turn(rows: int, cols: int, dtype: np.dtype) -> tuple[np.ndarray, np.ndarray]:
    """``(cos, sin)`` of the gradient's direction at the frequencies ``(u, v)`` of 1 to ``rows - 1``
    and 1 to ``cols - 1``: ``(v, u) / |(u, v)|``, in radians per sample."""
    u = np.arange(1, rows)[:, None] * (np.pi / rows)
    v = np.arange(1, cols)[None, :] * (np.pi / cols)
    r = np.hypot(u, v)
    return (v / r).astype(dtype), (u / r).astype(dtype)


def precision(threshold: float) -> type:
    """The dtype the decoder turns the channels of a file of threshold ``T`` in."""
    return np.float32 if threshold >= SINGLE_FROM else np.float64


#: Samples of a channel from which its transforms run in as many threads as the process has cores
#: (scipy's ``workers``: the lines of a transform split between them, each line the same numbers):
#: a Riesz pair's restoration projects through four of them.
THREADS_FROM = 256 * 256


def _workers(x: np.ndarray) -> int:
    return CORES if x.size >= THREADS_FROM else 1


def _dct(x: np.ndarray, axis: int) -> np.ndarray:
    return fft.dct(x, 2, axis=axis, norm="ortho", workers=_workers(x))


def _dst(x: np.ndarray, axis: int) -> np.ndarray:
    return fft.dst(x, 2, axis=axis, norm="ortho", workers=_workers(x))


def _idct(x: np.ndarray, axis: int) -> np.ndarray:
    return fft.idct(x, 2, axis=axis, norm="ortho", workers=_workers(x))


def _idst(x: np.ndarray, axis: int) -> np.ndarray:
    return fft.idst(x, 2, axis=axis, norm="ortho", workers=_workers(x))


def forward(a: np.ndarray, b: np.ndarray, sign: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The Riesz pair ``(g, g')`` of the channels ``a`` (x: along the columns) and ``b`` (y: along
    the rows, times ``sign``).

    Parameters
    ----------
    a, b : ndarray, shape (H, W), float32 or float64
    sign : {1, -1}
        ``b`` is ``sign`` times the slope along the rows (:func:`oriented` chooses it).

    Returns
    -------
    g, g' : ndarray, shape (H, W), of the dtype of ``a`` (float32 or float64)
        ``g`` along the gradients, ``g'`` across them; ``||g||^2 + ||g'||^2 = ||a||^2 + ||b||^2``.

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[0:32, 0:48] / 32.0
    >>> height = np.sin(3 * x) * np.cos(2 * y)
    >>> a, b = np.gradient(height, axis=1), np.gradient(height, axis=0)
    >>> g, curl = forward(a, b)
    >>> bool(np.sum(curl**2) < 1e-3 * np.sum(g**2))
    True
    >>> back = inverse(g, curl)
    >>> bool(np.allclose(back[0], a) and np.allclose(back[1], b))
    True
    """
    return _pair(*_spectra(a, b), sign)


def oriented(a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """``(sign, g, g')``: :func:`forward` with the ``sign`` that leaves the smaller curl, +1 where
    ``b`` is the slope along the rows, -1 where it is its opposite (a map whose green axis points
    the other way); the two differ only in the sign of one cross term."""
    first, second = _spectra(a, b)
    c, s = _turn(*first.shape, first.dtype)
    rows, cols = first.shape
    cross = float(np.sum((s * first[1:, : cols - 1]) * (c * second[: rows - 1, 1:]), dtype=np.float64))
    sign = 1 if cross >= 0 else -1
    return sign, *_pair(first, second, sign)


def _spectra(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DST-II x DCT-II of ``a`` (frequencies ``(u, v + 1)``), DCT-II x DST-II of ``b`` (``(u + 1, v)``)."""
    dtype = np.result_type(a.dtype, np.float32)
    return _dst(_dct(np.asarray(a, dtype), 0), 1), _dct(_dst(np.asarray(b, dtype), 0), 1)


def _pair(first: np.ndarray, second: np.ndarray, sign: int) -> tuple[np.ndarray, np.ndarray]:
    """``(g, g')`` of the spectra of :func:`_spectra` (``second`` times ``sign``)."""
    along, across = np.empty_like(first), np.empty_like(first)  # (u, v) and (u + 1, v + 1)
    _turn_spectra(first, second, *_turn(*first.shape, first.dtype), sign, along, across, False)
    return _idct(_idct(along, 0), 1), _idst(_idst(across, 0), 1)


@njit(cache=True, nogil=True)
def _turn_spectra(x, y, c, s, sign, along, across, back):
    """The rotation at every frequency, in one pass (numpy's would make five temporaries of the
    image). Forward (``back`` False): ``x, y`` the spectra of ``a`` and ``b`` (``y`` times ``sign``),
    into those of ``g`` (``along``) and ``g'`` (``across``); back: ``x, y`` the spectra of ``g``
    and ``g'``, into those of ``a`` and ``b`` (``along``, ``across``; ``across`` times ``sign``)."""
    rows, cols = x.shape
    for i in range(rows):
        for j in range(cols):
            if back:
                if i > 0 and j < cols - 1:
                    along[i, j] = c[i - 1, j] * x[i, j + 1] + s[i - 1, j] * y[i - 1, j]
                if i < rows - 1 and j > 0:
                    across[i, j] = sign * (s[i, j - 1] * x[i + 1, j] - c[i, j - 1] * y[i, j - 1])
            else:
                if i > 0 and j > 0:
                    along[i, j] = c[i - 1, j - 1] * x[i, j - 1] + sign * s[i - 1, j - 1] * y[i - 1, j]
                if i < rows - 1 and j < cols - 1:
                    across[i, j] = s[i, j] * x[i + 1, j] - sign * c[i, j] * y[i, j + 1]
    # The frequencies of one of the two, one to one (the same assignments both ways).
    for j in range(cols - 1):
        if back:
            along[0, j] = x[0, j + 1]
            across[rows - 1, j + 1] = sign * y[rows - 1, j]
        else:
            along[0, j + 1] = x[0, j]
            across[rows - 1, j] = sign * y[rows - 1, j + 1]
    for i in range(rows - 1):
        if back:
            across[i, 0] = sign * x[i + 1, 0]
        else:
            along[i + 1, 0] = sign * y[i, 0]
    for i in range(rows):
        if back:
            along[i, cols - 1] = y[i, cols - 1]
        else:
            across[i, cols - 1] = x[i, cols - 1]
    if back:
        across[rows - 1, 0] = sign * x[0, 0]
    else:
        along[0, 0] = sign * y[rows - 1, 0]


def inverse(g: np.ndarray, curl: np.ndarray, sign: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The channels ``(a, b)`` of the Riesz pair ``(g, g')`` (the inverse of :func:`forward`)."""
    dtype = np.result_type(g.dtype, np.float32)
    along = _dct(_dct(np.asarray(g, dtype), 0), 1)
    across = _dst(_dst(np.asarray(curl, dtype), 0), 1)
    first, second = np.empty_like(along), np.empty_like(along)
    _turn_spectra(along, across, *_turn(*along.shape, dtype), sign, first, second, True)
    return _idst(_idct(first, 0), 1), _idct(_idst(second, 0), 1)
