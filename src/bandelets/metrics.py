"""Distortion and rate measures.

Every rate is a file: ``bpp = 8 * bytes / (H * W)``. Every PSNR compares a decoded array
with its source.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

from .format.fields import Kind
from .format.samples import as_read
from .runtime.threads import CORES, by_rows, workers
from .transform.normals import THREADED_PIXELS, as_real, hemisphere, unit_length, unit_vectors, with_z

__all__ = [
    "AngularError",
    "angles",
    "angular_error",
    "bits_per_pixel",
    "bd_psnr",
    "psnr",
    "psnr_against",
    "psnr_of_channels",
    "peak",
]


def bits_per_pixel(n_bytes: int, shape: tuple[int, ...]) -> float:
    """``8 * n_bytes / (H * W)`` for an image of ``shape`` (H, W[, C])."""
    return 8.0 * n_bytes / (shape[0] * shape[1])


class AngularError(NamedTuple):
    """Angles between original and decoded normals, in degrees."""

    mean: float
    p99: float
    max: float


def angular_error(reference: np.ndarray, decoded: np.ndarray) -> AngularError:
    """Mean, 99th percentile and largest angle between the normals of two maps, in degrees.

    Parameters
    ----------
    reference, decoded : ndarray, shape (H, W, 3), or (H, W, 2) for ``x, y`` maps (:func:`with_z`)
        Vectors of any length (both are renormalised; a zero vector counts as +z).

    Returns
    -------
    AngularError

    Examples
    --------
    >>> up = np.array([[[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]])
    >>> turned = np.array([[[0.0, 0.0, 1.0], [np.sin(np.radians(3.0)), 0.0, np.cos(np.radians(3.0))]]])
    >>> [round(v, 6) for v in angular_error(up, turned)]  # mean, 99th percentile, max
    [1.5, 2.97, 3.0]
    """
    errors = angles(reference, decoded)
    return AngularError(float(errors.mean()), float(np.percentile(errors, 99)), float(errors.max()))


def angles(reference: np.ndarray, decoded: np.ndarray) -> np.ndarray:
    """The angle between the normals of two maps at each pixel, in degrees, shape (H * W,)
    (arguments of :func:`angular_error`)."""
    a, b = (np.asarray(v, np.float64) for v in (reference, decoded))
    a, b = (unit_vectors(with_z(v) if v.shape[-1] == 2 else v) for v in (a, b))
    if a.shape != b.shape or a.shape[-1] != 3:
        raise ValueError(f"angular_error needs two maps of normals of one shape, got {a.shape} and {b.shape}")
    # atan2 of the cross and dot products: exact for small angles, where arccos(dot) is not.
    sine = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(sine, np.einsum("...c,...c->...", a, b))).ravel()


def peak(reference: np.ndarray, kind: str = "image") -> float:
    """Peak value of the PSNR of each kind.

    * image: the value range of the reference (1 when it is constant);
    * normal-map: ``max |f|``, as in the paper (section 6);
    * geometry-image: the diagonal of the bounding box of the positions.
    """
    reference = np.asarray(reference, np.float64)
    if kind == Kind.NORMAL_MAP:
        return float(np.max(np.abs(reference)))
    if kind == Kind.GEOMETRY_IMAGE:
        flat = reference.reshape(-1, reference.shape[-1])
        return float(np.linalg.norm(np.ptp(flat, axis=0)))
    span = float(np.ptp(reference))
    return span if span > 0 else 1.0


def psnr(reference: np.ndarray, decoded: np.ndarray, kind: str = "image") -> float:
    """``20 log10(peak / RMSE)`` in dB (``inf`` when equal).

    For a normal map both arrays are compared after renormalising them to unit vectors, as the
    paper measures; a map of shape (H, W, 2) holds ``x, y`` (:func:`with_z`). The decoder already
    renormalises, but a decoded map written in 8 or 16-bit samples and read back is no longer of
    unit length: a renderer renormalises it, and so do the anchors' decoded files
    (:func:`bandelets.apps.anchors.decode`).
    """
    return psnr_against(reference, kind)(decoded)


def psnr_against(reference: np.ndarray, kind: str = "image") -> Callable[[np.ndarray], float]:
    """:func:`psnr` of any decoded array against ``reference``, which is prepared once (the
    encoder measures every restoration iteration)."""
    reference = np.asarray(reference, np.float64)
    # A normal map of x, y alone is compared on x, y, z (as a BC5 decoder rebuilds z).
    xy = kind == Kind.NORMAL_MAP and reference.shape[-1] == 2
    if kind == Kind.NORMAL_MAP:
        reference = unit_vectors(with_z(reference) if xy else reference)
    top = peak(reference, kind)

    def measure(decoded: np.ndarray) -> float:
        decoded = np.asarray(decoded, np.float64)
        decoded = (with_z(decoded) if xy else decoded).reshape(reference.shape)
        if kind == Kind.NORMAL_MAP:
            decoded = unit_vectors(decoded)
        rmse = float(np.sqrt(np.mean((reference - decoded) ** 2)))
        return float("inf") if rmse == 0 else 20.0 * np.log10(top / rmse)

    return measure


def psnr_of_channels(
    reference: np.ndarray, kind: str = "image", depth: int = 0, equidistant: bool = False
) -> Callable[[np.ndarray], float]:
    """:func:`psnr_against` ``reference`` of the image that decoded channels stand for, measured
    from the channels themselves, without making that image: the encoder measures every
    restoration iteration, and making the image took as long as the iteration.

    The callable takes ``(C, H', W')`` channels, ``H' >= H``, ``W' >= W`` (padded; cropped to the
    reference). For a normal map, two channels are ``x, y`` (``z = sqrt(max(0, 1 - x^2 - y^2))``)
    (with ``equidistant``: azimuthal equidistant coordinates, :func:`unit_normals`) and three
    ``x, y, z``, all renormalised as :func:`unit_vectors` does; the error is summed in
    one pass, so the value may differ from :func:`psnr` of the decoded array in the last digits.
    A reference of two channels is a normal map of ``x, y`` (:func:`with_z`). With ``depth`` (8 or
    16) the image is measured as written in samples of that depth
    (:func:`bandelets.io.files.as_read`): what the user gets.
    """
    reference = np.asarray(reference, np.float64)
    if kind != Kind.NORMAL_MAP:
        measure = psnr_against(reference, kind)
        rows, cols = reference.shape[:2]
        return lambda channels: measure(as_read(np.moveaxis(channels[:, :rows, :cols], 0, -1), kind, depth))
    reference = by_rows(unit_vectors, with_z(reference) if reference.shape[-1] == 2 else reference)
    top, samples = peak(reference, kind), reference.size
    # Only the planes are kept: the encoder holds this through rate control.
    planes = np.ascontiguousarray(np.moveaxis(reference, -1, 0))
    del reference

    def measure(channels: np.ndarray) -> float:
        channels = as_real(channels)
        args = (planes, channels, 2**depth - 1 if depth else 0, equidistant)
        rows = planes.shape[1]
        if CORES == 1 or planes[0].size < THREADED_PIXELS:
            sse = _normal_map_sse(*args, 0, rows)
        else:  # the two halves of the rows in two threads (the kernel releases the GIL)
            second = workers().submit(_normal_map_sse, *args, rows // 2, rows)
            sse = _normal_map_sse(*args, 0, rows // 2) + second.result()
        rmse = float(np.sqrt(sse / samples))
        return float("inf") if rmse == 0 else 20.0 * np.log10(top / rmse)

    return measure


@njit(cache=True, nogil=True)
def _as_sample(v, top):
    """A component in [-1, 1] as a sample of ``top + 1`` levels reads back
    (:func:`bandelets.io.files.as_read`); unchanged for ``top = 0`` (floats)."""
    if top == 0:
        return v
    return np.rint(min(max((v + 1.0) / 2.0, 0.0), 1.0) * top) / top * 2.0 - 1.0


@njit(cache=True, nogil=True, inline="always")
def _row_errors(r0, r1, r2, x, y, z, errors, top, two, equidistant):
    """Squared error of each unit vector of one row (``two``: two coded channels,
    :func:`_hemisphere`) against the reference row ``r0, r1, r2``: a loop without a sum, which
    the compiler vectorises."""
    for j in range(errors.shape[0]):
        u, v, w = np.float64(x[j]), np.float64(y[j]), np.float64(z[j])  # float32 channels: exactly
        a, b, c = hemisphere(u, v, equidistant) if two else (u, v, w)
        a, b, c = unit_length(a, b, c)
        if top != 0:  # written in samples, read back and renormalised (psnr)
            a, b, c = unit_length(_as_sample(a, top), _as_sample(b, top), _as_sample(c, top))
        errors[j] = (r0[j] - a) ** 2 + (r1[j] - b) ** 2 + (r2[j] - c) ** 2


@njit(cache=True, nogil=True)
def _normal_map_sse(planes, channels, top, equidistant, first, last):
    """Squared error of the unit vectors of ``channels`` (2: :func:`_hemisphere`), as samples of ``top + 1``
    levels (0: floats), against the reference ``planes`` (3, H, W), over the rows ``first`` to
    ``last``, summed in raster order."""
    cols = planes.shape[2]
    errors = np.empty(cols)
    sse = 0.0
    for i in range(first, last):
        # One call per case: the compiler drops the unused branch from each loop.
        if channels.shape[0] == 2:
            x, y = channels[0, i, :cols], channels[1, i, :cols]
            _row_errors(planes[0, i], planes[1, i], planes[2, i], x, y, y, errors, top, True, equidistant)
        else:
            x, y, z = channels[0, i, :cols], channels[1, i, :cols], channels[2, i, :cols]
            _row_errors(planes[0, i], planes[1, i], planes[2, i], x, y, z, errors, top, False, False)
        for j in range(cols):
            sse += errors[j]
    return sse


def bd_psnr(rates_a, psnrs_a, rates_b, psnrs_b) -> float:
    """Bjontegaard delta PSNR of curve A over curve B, in dB.

    Each curve's PSNR is fitted by a cubic polynomial in ``log10(rate)``; the fits are
    averaged over the rate interval both curves cover, and B's average is subtracted from A's.
    Each curve needs at least four points.
    """
    la, lb = np.log10(np.asarray(rates_a, float)), np.log10(np.asarray(rates_b, float))
    fa = np.polyfit(la, np.asarray(psnrs_a, float), 3)
    fb = np.polyfit(lb, np.asarray(psnrs_b, float), 3)
    lo, hi = max(la.min(), lb.min()), min(la.max(), lb.max())
    if hi <= lo:
        raise ValueError("the two rate-distortion curves do not overlap")
    ia, ib = np.polyint(fa), np.polyint(fb)
    mean_a = (np.polyval(ia, hi) - np.polyval(ia, lo)) / (hi - lo)
    mean_b = (np.polyval(ib, hi) - np.polyval(ib, lo)) / (hi - lo)
    return float(mean_a - mean_b)
