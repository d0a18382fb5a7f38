"""The one line ``encode`` and ``decode`` print on stderr when they succeed, as ``cjxl`` does."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..format.fields import LOSSLESS, Kind
from ..format.samples import as_read
from ..metrics import angular_error, bits_per_pixel

__all__ = ["decode_summary", "encode_summary", "lengths_note"]

#: Input vector lengths further than this from 1 are named in the summary (renormalisation
#: changes such a map: ``--kind image`` keeps the lengths).
LENGTH_TOLERANCE = 0.05


def _samples(shape: tuple[int, ...], depth: int) -> str:
    channels = shape[2] if len(shape) == 3 else 1
    return f"{shape[1]} x {shape[0]} x {channels}, {f'{depth}-bit' if depth else 'float'}"


def lengths_note(vectors: np.ndarray) -> str:
    """``"; input vector lengths 0.11 to 1.37 (renormalised)"`` when they are far from 1, else ``""``."""
    lengths = np.sqrt(np.einsum("...c,...c->...", vectors, vectors))
    low, high = float(lengths.min()), float(lengths.max())
    if 1 - LENGTH_TOLERANCE <= low and high <= 1 + LENGTH_TOLERANCE:
        return ""
    return f"; input vector lengths {low:.2f} to {high:.2f} (renormalised; --kind image keeps them)"


def encode_summary(
    source: str,
    output: str,
    array: np.ndarray,
    depth: int,
    kind: str,
    xy: bool,
    encoded,
    seconds: float,
    bpp: float | None = None,
) -> str:
    """``source (W x H x C, depth) -> output: bytes, bpp, PSNR[, angular error], seconds``.

    ``encoded`` is the :class:`bandelets.codec.encoder.Encoded` of ``array`` (measured), whose PSNR is that
    of the decoded file at the source's ``depth``; the angles are measured there too. A lossless
    file says so in place of its PSNR, and that it is smaller than the ``bpp`` asked, if one was.
    """
    n = len(encoded.data)
    rate = bits_per_pixel(n, array.shape)
    if encoded.header is not None and encoded.header.transform == LOSSLESS:
        asked = f" (exact, smaller than the {bpp:g} bpp asked; --no-lossless for a lossy file)" if bpp else ""
        return (
            f"{source} ({_samples(array.shape, depth)}) -> {output}: {n} bytes, {rate:.3f} bpp, "
            f"lossless{asked}, {seconds:.2f} s"
        )
    line = (
        f"{source} ({_samples(array.shape, depth)}) -> {output}: {n} bytes, "
        f"{rate:.3f} bpp, PSNR {encoded.psnr:.2f} dB"
    )
    note = ""
    if kind == Kind.NORMAL_MAP:
        reference = array[..., :2] if xy else array
        error = encoded.angles or angular_error(reference, as_read(encoded.decoded, kind, depth))
        line += f", angle mean {error.mean:.2f} p99 {error.p99:.2f} max {error.max:.1f} deg"
        if reference.shape[-1] == 3:
            note = lengths_note(reference)
    return f"{line}, {seconds:.2f} s{note}"


def decode_summary(source: str, output: str, decoded: np.ndarray, header, seconds: float) -> str:
    """``source -> output: W x H x C, samples written, seconds``."""
    suffix = Path(output).suffix.lower()
    # bandelets.io.files.write_array: PNG and TIFF at the source's depth (PNG: 16 bits for floats).
    depth = (header.depth or 16 * (suffix == ".png")) if suffix in (".png", ".tif", ".tiff") else 0
    xy = suffix == ".png" and decoded.ndim == 3 and decoded.shape[2] == 2  # written as RGB
    shape = decoded.shape[:2] + (3,) if xy else decoded.shape
    return f"{source} -> {output}: {_samples(shape, depth)}, {seconds:.2f} s"
