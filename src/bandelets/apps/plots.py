"""Figures: PSNR against rate, one panel per input (matplotlib, imported when drawing)."""

from __future__ import annotations

import io
from pathlib import Path

from ..io.files import write_atomic

__all__ = ["VALUES", "rate_key", "rd_figure", "save"]

#: Line style of each codec, so that a codec looks the same in every panel and figure.
_STYLE = {
    "bandelet": ("tab:red", "o", "-"),
    "wavelet": ("tab:orange", "s", "--"),
    "jpeg2000": ("tab:blue", "^", "-."),
    "avif": ("tab:green", "D", ":"),
    "jpegxl": ("tab:purple", "v", (0, (3, 1, 1, 1))),
    "draco": ("tab:brown", "P", "-."),
}


def save(figure, path: Path, dpi: int = 100) -> None:
    """Write a matplotlib figure as PNG through :func:`bandelets.io.files.write_atomic`."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    write_atomic(path, buffer.getvalue())


def rate_key(rows: list[dict]) -> str:
    """The rate of the rows: ``"bpv"`` (bits per vertex) for meshes, else ``"bpp"``."""
    return "bpv" if rows and "bpv" in rows[0] else "bpp"


#: What a figure can plot against the rate: the row's key and the axis label.
VALUES = {
    "psnr": "PSNR (dB)",
    "angle_mean": "mean angular error (degrees)",
    "angle_p99": "99th percentile angular error (degrees)",
}


def rd_figure(rows: list[dict], path: Path, value: str = "psnr") -> None:
    """Plot PSNR (dB) or an angular error against bits per pixel (or per vertex) for every codec,
    one panel per input.

    Parameters
    ----------
    rows : list of dict
        Points with keys ``input, codec, bpp, psnr`` (as :func:`bandelets.apps.rd.run` returns),
        ``bpv`` instead of ``bpp`` for meshes, ``angle_mean, angle_p99`` for normal maps.
    path : Path
        The PNG to write.
    value : {"psnr", "angle_mean", "angle_p99"}
        What to plot (:data:`VALUES`); rows without it are left out. Angles use a log scale.
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import FormatStrFormatter

    rate = rate_key(rows)
    inputs = list(dict.fromkeys(r["input"] for r in rows)) or ["(no points)"]
    columns = min(3, len(inputs))
    lines = -(-len(inputs) // columns)
    figure = Figure(figsize=(4.6 * columns, 3.6 * lines), layout="constrained")
    axes = figure.subplots(lines, columns, squeeze=False).ravel()
    for ax, name in zip(axes, inputs, strict=False):
        curves = [r for r in rows if r["input"] == name and value in r]
        for codec in dict.fromkeys(r["codec"] for r in curves):
            points = sorted((r[rate], r[value]) for r in curves if r["codec"] == codec)
            colour, marker, style = _STYLE.get(codec, ("black", "x", "-"))
            ax.plot(*zip(*points, strict=True), color=colour, marker=marker, linestyle=style, label=codec)
        ax.set_xscale("log", base=2)
        ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.set_title(name)
        ax.set_xlabel("bits per vertex (file size)" if rate == "bpv" else "bits per pixel (file size)")
        ax.set_ylabel(VALUES[value])
        if value != "psnr":
            ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        if curves:
            ax.legend(fontsize="small")
    for ax in axes[len(inputs) :]:
        ax.set_visible(False)
    save(figure, path)
