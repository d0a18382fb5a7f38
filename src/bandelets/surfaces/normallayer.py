"""A second layer of a chart mesh record: each vertex moved along its normal by a coded amount.

The Hausdorff distance between two surfaces sees only how far a vertex lies off the other
surface, not where it slides along it. The geometry image of a coarse scan (about one pixel per
vertex) spends most of its bits on detail at the scale of the vertices, which a wavelet codes
poorly. So the encoder codes the image at part of the budget, reads the vertices back as the
decoder will (``P``), takes the normals of that decoded mesh (``N``, area-weighted, which the
decoder computes alike), and codes one number a vertex, the input's offset along the normal
``(X - P) . N`` quantized with a uniform step (zigzag, then adaptive Elias-gamma codes of the
range coder); the decoder returns ``P + q * step * N``. The tangential error of ``P`` stays.

Measured on fertility.off at Draco quantization 7's size (8.88 bits per vertex, the faces 2.53
of them): the image alone at all the bits 58.76 dB; with 60 % of the position bits to the image
and the rest to this layer 63.57 dB (45 %: 61.79, 75 %: 62.87).
"""

from __future__ import annotations

import numpy as np

from ..coding.rangecoder import Coder, CorruptStream, code_positive

__all__ = ["IMAGE_SHARES", "apply", "decode", "encode", "vertex_normals"]

#: Shares of the position bits the encoder tries giving the image (the rest to this layer).
IMAGE_SHARES = (0.45, 0.6, 0.75)
#: Contexts of the range coder (one Elias-gamma prefix model).
_CONTEXTS = 32
#: Bisection steps of the quantization step that fills the layer's budget.
_SEARCH_STEPS = 30


def vertex_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals at the vertices: the sum of their faces' area-weighted normals."""
    corner = positions[faces]
    face_normals = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
    normals = np.zeros_like(positions)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_normals)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 0, normals / np.where(length > 0, length, 1.0), 0.0)


def _code(q: np.ndarray) -> bytes:
    coder = Coder(_CONTEXTS, capacity=8 * len(q) + 64)
    code_positive(coder, 2 * np.abs(q) - (q < 0) + 1, np.zeros(len(q), np.int64))
    return coder.finish()


def encode(offsets: np.ndarray, bits: float, scale: float) -> tuple[float, bytes] | None:
    """The finest step (bisection between ``scale * 1e-7`` and ``scale``) whose coded offsets
    fit in ``bits``, and the stream; ``None`` if even the coarsest does not fit."""
    low, high = 1e-7 * scale, float(scale)
    best = None
    for _ in range(_SEARCH_STEPS):
        step = float(np.float32(np.sqrt(low * high)))
        data = _code(np.rint(offsets / step).astype(np.int64))
        if 8 * len(data) > bits:
            low = step
        else:
            high, best = step, (step, data)
    if best is None:
        high = float(np.float32(high))
        data = _code(np.rint(offsets / high).astype(np.int64))
        best = (high, data) if 8 * len(data) <= bits else None
    return best


def decode(data: bytes, n_vertices: int) -> np.ndarray:
    """The quantized offsets of :func:`encode` (``ValueError`` if corrupt)."""
    coder = Coder(_CONTEXTS, data)
    try:
        values = code_positive(coder, np.ones(n_vertices, np.int64), np.zeros(n_vertices, np.int64))
        coder.check()
    except CorruptStream:
        raise ValueError("corrupt chart mesh file (normal layer)") from None
    return np.where(values % 2 == 1, values // 2, -(values // 2))


def apply(positions: np.ndarray, faces: np.ndarray, step: float, q: np.ndarray) -> np.ndarray:
    """The positions moved along the normals of their mesh by ``q * step``."""
    return positions + (q * step)[:, None] * vertex_normals(positions, faces)
