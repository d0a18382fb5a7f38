"""Local frames for geometry images: the paper's fix for tangential drift (section 6).

The Hausdorff distance between surfaces hardly sees an error that slides a point along the
surface, but the L2 error of the three position channels counts it in full. The detail
coefficients of the positions are therefore expressed, at every place, in a local frame
(normal, first tangent, second tangent), and the normal component is multiplied by a weight
``w`` before the basis search and the quantization, and divided by it after: its error is
``w`` times smaller for the same threshold. The paper uses 3; 2 measures a little better
(``benchmarks/rd_meshes.py``) and is the default of :func:`bandelets.encode`.

The decoder must know the frames of a level before it can turn its details back, so they come
from what it has decoded before them: the approximation and the coarser levels, dequantized
and back in the global frame. Their wavelet reconstruction (every finer detail set to 0) is a
smooth surface at full resolution; the tangents are its differences between neighbouring
pixels along the columns and along the rows, the normal their cross product. A detail
coefficient of level ``j`` at ``(i, k)`` of its subband takes the frame of pixel
``(2**j i + 2**(j-1), 2**j k + 2**(j-1))``.
Each rotation is orthonormal, so the coefficients keep their energy and the Lagrangian and
the quantizer work unchanged on them.
"""

from __future__ import annotations

import numpy as np

from .wavelets import subband_slices, waverec

__all__ = ["frame_field", "level_frames", "rotate", "to_global"]

# The cross product of the tangents is taken as degenerate below this fraction of the
# product of their lengths (tangents parallel), or when either tangent is zero.
_DEGENERATE = 1e-9


def frame_field(du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Orthonormal frames from the tangents of a surface.

    Parameters
    ----------
    du, dv : ndarray of float, shape (..., 3)
        Tangents along the columns and along the rows (any lengths).

    Returns
    -------
    ndarray of float, shape (..., 3, 3)
        ``[..., 0, :]`` the unit normal, ``[..., 1, :]`` the unit tangent along the columns,
        ``[..., 2, :]`` their cross product. Where the surface is degenerate (a tangent is 0,
        or the two are parallel) the frame is fixed: normal z, tangents x and y, so that the
        encoder and the decoder agree whatever the data.
    """
    normal = np.cross(du, dv)
    length_n = np.linalg.norm(normal, axis=-1, keepdims=True)
    length_u = np.linalg.norm(du, axis=-1, keepdims=True)
    length_v = np.linalg.norm(dv, axis=-1, keepdims=True)
    good = (length_n > _DEGENERATE * length_u * length_v) & (length_u > 0) & (length_v > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = np.where(good, normal / length_n, (0.0, 0.0, 1.0))
        tangent = np.where(good, du / length_u, (1.0, 0.0, 0.0))
    # du is orthogonal to du x dv already: the cross product completes the frame.
    return np.stack([normal, tangent, np.cross(normal, tangent)], axis=-2)


def level_frames(
    coefficients: list[np.ndarray], level: int, wavelet: str, levels: int, extension: str
) -> np.ndarray:
    """The frame of every position of the detail subbands of ``level`` (1 = finest).

    Parameters
    ----------
    coefficients : list of 3 ndarray, shape (H, W)
        Normalised wavelet coefficients of x, y, z (Mallat layout); only the approximation and
        the levels coarser than ``level`` are read, in the global frame.
    level : int
    wavelet, levels, extension
        The transform of ``coefficients`` (:func:`bandelets.wavelets.waverec`).

    Returns
    -------
    ndarray of float, shape (H / 2**level, W / 2**level, 3, 3)
        Rows normal, tangent, tangent (:func:`frame_field`).
    """
    shape = coefficients[0].shape
    h, w = shape[0] >> level, shape[1] >> level
    surface = np.empty(shape + (3,))
    for k, c in enumerate(coefficients):
        coarse = np.zeros(shape)
        coarse[:h, :w] = c[:h, :w]
        surface[..., k] = waverec(coarse, wavelet, levels, extension)
    rows = np.minimum((np.arange(h) << level) + (1 << (level - 1)), shape[0] - 1)
    cols = np.minimum((np.arange(w) << level) + (1 << (level - 1)), shape[1] - 1)
    # Differences of the neighbouring pixels (one-sided on the border); only their
    # directions matter.
    right, left = np.minimum(cols + 1, shape[1] - 1), np.maximum(cols - 1, 0)
    down, up = np.minimum(rows + 1, shape[0] - 1), np.maximum(rows - 1, 0)
    du = surface[np.ix_(rows, right)] - surface[np.ix_(rows, left)]
    dv = surface[np.ix_(down, cols)] - surface[np.ix_(up, cols)]
    return frame_field(du, dv)


def rotate(
    coefficients: list[np.ndarray], frames: np.ndarray, level: int, levels: int, weight: float, *, local: bool
) -> None:
    """Turn the three detail subbands of ``level`` into (``local``) or out of the frames, in place.

    Parameters
    ----------
    coefficients : list of 3 ndarray, shape (H, W)
        Channels x, y, z; in the local frames, normal (times ``weight``), tangent, tangent.
    frames : ndarray, shape (H / 2**level, W / 2**level, 3, 3)
        :func:`level_frames`.
    level, levels : int
    weight : float
        Factor of the normal component.
    local : bool
        True: global to local; False: back.
    """
    shape = coefficients[0].shape
    scale = np.array([weight, 1.0, 1.0])
    for where in (s for lv, _, s in subband_slices(shape, levels) if lv == level):
        v = np.stack([c[where] for c in coefficients], axis=-1)  # (h, w, 3)
        if local:
            v = np.einsum("...ij,...j->...i", frames, v) * scale
        else:
            v = np.einsum("...ji,...j->...i", frames, v / scale)
        for k, c in enumerate(coefficients):
            c[where] = v[..., k]


def to_global(
    coefficients: list[np.ndarray], wavelet: str, levels: int, extension: str, weight: float
) -> None:
    """Every level back from the local frames, coarsest first (as the decoder does), in place.

    ``coefficients`` (3 arrays, shape (H, W), local frames) hold the decoded values; the
    frames of each level come from the levels already turned back.
    """
    for level in range(levels, 0, -1):
        frames = level_frames(coefficients, level, wavelet, levels, extension)
        rotate(coefficients, frames, level, levels, weight, local=False)
