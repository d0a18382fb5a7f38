"""The multi-chart geometry image: the smoothest image through the vertices, and the vertices back.

The decoder reads each vertex by bilinear interpolation at its place in the layout
(:mod:`.charts`); the rest of the image is free. :func:`fit` makes it the smoothest image (least
thin-plate energy, the squared discrete Laplacian) whose bilinear reads at the vertices are the
positions (a penalty of weight :data:`FIT_WEIGHT`): between the vertices, between the charts'
squares and in the unused corner of the image it then varies smoothly, and the wavelets spend
almost nothing there. Measured on fertility.off at 8.9 bits per vertex against rasterizing the
mesh's triangles and filling the rest by push-pull: +1.2 dB Hausdorff PSNR (and a higher ceiling
uncoded, 68.1 dB against 64.5 at 128 x 128).
"""

from __future__ import annotations

import numpy as np

__all__ = ["DIRECT_UP_TO", "FIT_WEIGHT", "bilinear_matrix", "fit", "push_pull", "sample"]

#: Weight of the reads at the vertices against the smoothness (the Laplacian's squares): 10
#: and 1000 measured 1.6 and 1.9 dB below 100 (fertility.off, 8.9 bits per vertex).
FIT_WEIGHT = 100.0
#: Largest image side solved directly (sparse LU: 4 s at 256 x 256); above, conjugate gradients
#: from a push-pull start, in bounded time.
DIRECT_UP_TO = 256
CG_STEPS = 400


def _corners(pixels: np.ndarray, side: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r = np.clip(pixels[:, 0], 0, side - 1)
    c = np.clip(pixels[:, 1], 0, side - 1)
    r0 = np.minimum(np.floor(r).astype(np.int64), side - 2)
    c0 = np.minimum(np.floor(c).astype(np.int64), side - 2)
    return r0, c0, r - r0, c - c0


def bilinear_matrix(pixels: np.ndarray, side: int):
    """The sparse (K, side^2) matrix of bilinear reads at (row, column) points."""
    from scipy.sparse import coo_matrix

    r0, c0, fr, fc = _corners(pixels, side)
    columns = np.stack(
        [r0 * side + c0, r0 * side + c0 + 1, (r0 + 1) * side + c0, (r0 + 1) * side + c0 + 1], 1
    )
    weights = np.stack([(1 - fr) * (1 - fc), (1 - fr) * fc, fr * (1 - fc), fr * fc], 1)
    rows = np.repeat(np.arange(len(pixels)), 4)
    return coo_matrix((weights.ravel(), (rows, columns.ravel())), shape=(len(pixels), side * side)).tocsr()


def _laplacian(side: int):
    from scipy.sparse import diags, identity, kron

    main = np.full(side, -2.0)
    main[[0, -1]] = -1.0  # mirrored border: no pull towards zero outside
    second = diags([np.ones(side - 1), main, np.ones(side - 1)], [-1, 0, 1])
    return kron(second, identity(side)) + kron(identity(side), second)


def fit(pixels: np.ndarray, values: np.ndarray, side: int, weight: float = FIT_WEIGHT) -> np.ndarray:
    """The smoothest ``side x side`` image whose bilinear reads at ``pixels`` are ``values``.

    Parameters
    ----------
    pixels : ndarray of float, shape (K, 2)
        (row, column) of the vertices, pixel centres at integers.
    values : ndarray of float, shape (K, C)
    side : int
    weight : float
        Weight of the reads against the thin-plate energy.

    Returns
    -------
    ndarray of float, shape (side, side, C)
    """
    from scipy.sparse import identity
    from scipy.sparse.linalg import cg, spsolve

    reads = bilinear_matrix(pixels, side)
    laplacian = _laplacian(side)
    system = (weight * (reads.T @ reads) + laplacian.T @ laplacian + 1e-9 * identity(side * side)).tocsc()
    rhs = weight * (reads.T @ values)
    if side <= DIRECT_UP_TO:
        solution = spsolve(system, rhs).reshape(side * side, -1)
    else:
        start = push_pull(pixels, values, side).reshape(side * side, -1)
        solution = np.column_stack(
            [cg(system, rhs[:, k], x0=start[:, k], maxiter=CG_STEPS)[0] for k in range(values.shape[1])]
        )
    return solution.reshape(side, side, -1)


def push_pull(pixels: np.ndarray, values: np.ndarray, side: int) -> np.ndarray:
    """A smooth image through the points: each splatted on its nearest pixel (averaged), the
    empty pixels filled from averages down a pyramid, brought back up by bilinear steps."""
    nearest = np.clip(np.rint(pixels).astype(np.int64), 0, side - 1)
    index = nearest[:, 0] * side + nearest[:, 1]
    weight = np.bincount(index, minlength=side * side).reshape(side, side).astype(np.float64)
    total = np.stack(
        [np.bincount(index, values[:, k], minlength=side * side) for k in range(values.shape[1])], -1
    ).reshape(side, side, -1)
    levels = [(total, weight)]
    while min(total.shape[:2]) > 1:
        pad = ((0, total.shape[0] % 2), (0, total.shape[1] % 2))
        total, weight = np.pad(total, pad + ((0, 0),)), np.pad(weight, pad)
        total = total[0::2, 0::2] + total[1::2, 0::2] + total[0::2, 1::2] + total[1::2, 1::2]
        weight = weight[0::2, 0::2] + weight[1::2, 0::2] + weight[0::2, 1::2] + weight[1::2, 1::2]
        levels.append((total, weight))
    total, weight = levels[-1]
    estimate = total / np.maximum(weight, 1e-300)[..., None]
    for total, weight in reversed(levels[:-1]):
        h, w = weight.shape
        coarse = np.pad(estimate, ((1, 1), (1, 1), (0, 0)), mode="edge")
        up = _upsample(coarse)[2 : 2 * estimate.shape[0] + 2, 2 : 2 * estimate.shape[1] + 2][:h, :w]
        share = np.minimum(weight, 1.0)[..., None]  # where no point fell, the coarser estimate
        estimate = share * total / np.maximum(weight, 1e-300)[..., None] + (1 - share) * up
    return estimate


def _upsample(x: np.ndarray) -> np.ndarray:
    """Twice the size, each new pixel 3/4 of its nearest coarse pixel and 1/4 of the next."""
    rows = np.empty((2 * x.shape[0], x.shape[1], x.shape[2]))
    rows[0::2] = 0.75 * x + 0.25 * np.roll(x, 1, axis=0)
    rows[1::2] = 0.75 * x + 0.25 * np.roll(x, -1, axis=0)
    out = np.empty((rows.shape[0], 2 * x.shape[1], x.shape[2]))
    out[:, 0::2] = 0.75 * rows + 0.25 * np.roll(rows, 1, axis=1)
    out[:, 1::2] = 0.75 * rows + 0.25 * np.roll(rows, -1, axis=1)
    return out


def sample(image: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``image`` at (row, column) points, shape (K, C)."""
    r0, c0, fr, fc = _corners(pixels, image.shape[0])
    fr, fc = fr[:, None], fc[:, None]
    return (
        (1 - fr) * (1 - fc) * image[r0, c0]
        + (1 - fr) * fc * image[r0, c0 + 1]
        + fr * (1 - fc) * image[r0 + 1, c0]
        + fr * fc * image[r0 + 1, c0 + 1]
    )
