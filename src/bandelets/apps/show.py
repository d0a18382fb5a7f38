"""``bandelets show``: the geometry a .bdl file chose, drawn like the paper's figure 6.

The decoded wavelet coefficients are laid out as the codec sees them (Mallat layout, coarse
levels top left), each subband shaded by the magnitude of its coefficients summed over the
channels; every square of every quadtree is outlined, and a segment through its centre
shows the direction along which it was bandeletized (none for a square left as wavelets).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..coding.image import code_image, new_coders
from ..format.fields import LOSSLESS, padded_shape
from ..format.header import Header, unpack
from ..format.levels import parts
from ..format.quantizer import dequantize
from ..transform.bandeletize import debandeletize
from ..transform.geometry import directions
from ..transform.wavelets import subband_slices
from .plots import save

__all__ = ["geometry_figure", "wavelet_magnitudes"]


def wavelet_magnitudes(header: Header, trees: list, quantized: list[np.ndarray]) -> np.ndarray:
    """Decoded wavelet coefficients, ``|c|`` summed over channels, in the Mallat layout.

    Each detail subband's bandelet squares are transformed back to wavelet coefficients, so
    the picture shows the geometry the squares follow rather than their 1D coefficients.
    """
    shape = padded_shape((header.height, header.width), header.levels)
    total = np.zeros(shape)
    for q in quantized:
        c = dequantize(q.reshape(shape), header.threshold)
        for tree, (_, _, where) in zip(trees, subband_slices(shape, header.levels), strict=True):
            c[where] = debandeletize(c[where], tree, header.transform_1d)
        total += np.abs(c)
    return total


def _shaded(magnitudes: np.ndarray, header: Header) -> np.ndarray:
    """Each subband scaled to [0, 1] on its own (square root for contrast), 1 = white = 0."""
    out = np.ones_like(magnitudes)
    shape = magnitudes.shape
    regions = [where for _, _, where in subband_slices(shape, header.levels)]
    coarse = (slice(0, shape[0] >> header.levels), slice(0, shape[1] >> header.levels))
    for where in [coarse, *regions]:
        band = magnitudes[where]
        top = band.max()
        out[where] = 1.0 - np.sqrt(band / top) if top > 0 else 1.0
    return out


def _segments(header: Header, trees: list) -> tuple[list, list]:
    """Outlines of every square and direction segments of the bandeletized ones, (x, y)."""
    shape = padded_shape((header.height, header.width), header.levels)
    outlines, flows = [], []
    for tree, (_, _, where) in zip(trees, subband_slices(shape, header.levels), strict=True):
        rows, cols, widths, dirs = tree.leaves()
        for r, c, w, d in zip(rows + where[0].start, cols + where[1].start, widths, dirs, strict=True):
            x0, y0, x1, y1 = c - 0.5, r - 0.5, c + w - 0.5, r + w - 0.5
            outlines.append([(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)])
            if d >= 0:
                angle = directions(int(w))[0][d]
                dx, dy = 0.4 * w * np.cos(angle), 0.4 * w * np.sin(angle)
                cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
                flows.append([(cx - dx, cy - dy), (cx + dx, cy + dy)])
    return outlines, flows


def geometry_figure(data: bytes, path: Path) -> None:
    """Draw the quadtrees and directions of a .bdl file over its subbands into a PNG.

    Raises
    ------
    FormatError
        The file is not a readable .bdl file.
    ValueError
        A lossless file (:mod:`bandelets.coding.lossless`).
    """
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    header, streams = unpack(data)
    if header.transform == LOSSLESS:
        raise ValueError("a lossless file has no quadtrees, directions or subbands to show")
    trees, quantized, _ = code_image(new_coders(parts(streams, header.segments)), header)
    magnitudes = wavelet_magnitudes(header, trees, quantized)
    outlines, flows = _segments(header, trees)
    height, width = magnitudes.shape
    figure = Figure(figsize=(8, 8 * height / width + 0.4), layout="constrained")
    ax = figure.subplots()
    ax.imshow(_shaded(magnitudes, header), cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    ax.add_collection(LineCollection(outlines, colors="tab:red", linewidths=0.35))
    ax.add_collection(LineCollection(flows, colors="tab:blue", linewidths=0.8))
    ax.set_axis_off()
    ax.set_title(
        f"{header.width} x {header.height} {header.kind}, {header.transform}, T = {header.threshold:.3g}: "
        f"{len(outlines)} squares, {len(flows)} with a direction",
        fontsize="small",
    )
    save(figure, path, dpi=int(np.clip(2 * width / 8, 100, 256)))
