"""Values and the integer samples of a depth: what a file's ``depth`` field means.

A PNG or TIFF source holds unsigned samples of 8 or 16 bits; the codec works on values in
``[0, 1]`` (images) or ``[-1, 1]`` (normal maps). The file records the source's depth so that a
decoded image is written back as samples alike, and quality targets are measured on the values
as they will be written (:func:`as_read`).
"""

from __future__ import annotations

import numpy as np

from .fields import Kind

__all__ = ["as_read", "from_samples", "integer_samples", "to_samples"]


def to_samples(values: np.ndarray, kind: str, depth: int) -> np.ndarray:
    """Values as unsigned samples of ``depth`` bits (8 or 16): ``[0, 1]`` for images, ``[-1, 1]``
    for normal maps (``(v + 1) / 2``), rounded and clipped."""
    values = (values + 1.0) / 2.0 if kind == Kind.NORMAL_MAP else values
    top = 2**depth - 1
    return np.clip(np.rint(values * top), 0, top).astype(np.uint8 if depth == 8 else np.uint16)


def from_samples(pixels: np.ndarray, kind: str, depth: int) -> np.ndarray:
    """Float64 values of unsigned samples of ``depth`` bits (the inverse of :func:`to_samples`)."""
    values = pixels.astype(np.float64) / (2**depth - 1)
    return 2.0 * values - 1.0 if kind == Kind.NORMAL_MAP else values


def as_read(values: np.ndarray, kind: str, depth: int) -> np.ndarray:
    """``values`` as a file of ``depth`` bits (0: float, unchanged) would give them back: what a
    decoded image is once written at its source's depth."""
    return from_samples(to_samples(values, kind, depth), kind, depth) if depth else values


def integer_samples(values: np.ndarray, kind: str, depth: int = 0) -> tuple[np.ndarray, int]:
    """A normal map's ``uint8`` / ``uint16`` samples as values (as PNG samples) and their depth;
    ``ValueError`` for another integer type, which has no agreed scale, or a ``depth`` that
    disagrees. Floats, and integers of any other kind, are returned as they are."""
    if kind != Kind.NORMAL_MAP or values.dtype.kind not in "uib":
        return values, depth
    bits = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16}.get(values.dtype)
    if bits is None:
        raise ValueError(
            f"a normal map of {values.dtype} values has no agreed scale: give floats in [-1, 1] "
            "or uint8 / uint16 samples"
        )
    if depth not in (0, bits):
        raise ValueError(f"a normal map of {values.dtype} samples has depth {bits}, not {depth}")
    return from_samples(values, kind, bits), bits
