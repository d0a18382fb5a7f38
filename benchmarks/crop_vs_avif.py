"""A decoded crop of a real normal map beside AVIF's at the same file size (README's picture).

Encodes an 8-bit tangent-space normal map with bandelets (the defaults, ``kind="normal-map"``)
at a rate target, then finds the AVIF file (libavif through imagecodecs: 4:4:4, identity matrix
as for every normal map in BENCHMARKS.md, speed 2, 8 bits) of the quality level that gives the
largest file not above ours, decodes both, and draws a crop of the original, our decoded map and
AVIF's side by side, with each file's bytes and PSNR (whole map) in the titles, and under each
decoded crop its angle to the original, in degrees, on one colour scale.

Both decoded maps are measured as they would be stored at the source's depth (8-bit samples read
back and renormalised, :func:`bandelets.metrics.psnr` with ``kind="normal-map"``). The crop is the
128 x 128 window of the source with the most gradient energy (its busiest detail), not chosen
by either codec's error.

Run from the repository root (about a minute once the kernels are compiled)::

    python benchmarks/crop_vs_avif.py                       # writes docs/crop-vs-avif.png
    python benchmarks/crop_vs_avif.py --bpp 0.5 --crop 128 --out docs/crop-vs-avif.png

The source is the shared map ``../shared/data/normal-maps/godot_scifi_vent_decal_512.png``;
when it is absent, :func:`bandelets.samples.crease_normal_map` (512 x 512, stored as 8-bit).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import imagecodecs
import numpy as np

import bandelets
from bandelets.metrics import angles, psnr
from bandelets.samples import crease_normal_map

SHARED_MAP = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "normal-maps"
SHARED_MAP = SHARED_MAP / "godot_scifi_vent_decal_512.png"
AVIF_SPEED = 2


def to_values(samples: np.ndarray) -> np.ndarray:
    """8-bit samples as the vectors they store, in [-1, 1]."""
    return samples.astype(np.float64) / 255.0 * 2.0 - 1.0


def to_samples(values: np.ndarray) -> np.ndarray:
    """Vectors in [-1, 1] as 8-bit samples (what a PNG of the decoded map holds)."""
    return np.clip(np.rint((values + 1.0) / 2.0 * 255.0), 0, 255).astype(np.uint8)


def load_source() -> tuple[np.ndarray, str]:
    """The 8-bit RGB samples of the map and its name."""
    if SHARED_MAP.exists():
        samples = imagecodecs.png_decode(SHARED_MAP.read_bytes())
        return np.ascontiguousarray(samples[..., :3]), SHARED_MAP.name
    print(f"{SHARED_MAP} is absent: using the generated crease map", file=sys.stderr)
    return to_samples(crease_normal_map(512)), "crease_normal_map(512), 8-bit"


def avif(samples: np.ndarray, level: int) -> bytes:
    """AVIF file of the samples at a quality level (0 to 100)."""
    return imagecodecs.avif_encode(
        samples,
        level=level,
        speed=AVIF_SPEED,
        bitspersample=8,
        pixelformat=imagecodecs.AVIF.PIXEL_FORMAT.YUV444,
        matrix=imagecodecs.AVIF.MATRIX_COEFFICIENTS.IDENTITY,
    )


def avif_not_above(samples: np.ndarray, size: int) -> tuple[bytes, int]:
    """The largest AVIF file of at most ``size`` bytes over the quality levels, and its level.

    Bisection on the level (the size grows with it), then the levels around the one found are
    tried too, since the size is not strictly monotone in the level.
    """
    low, high = -1, 101  # low: a level known to fit (or none), high: one known not to
    while high - low > 1:
        middle = (low + high) // 2
        if len(avif(samples, middle)) <= size:
            low = middle
        else:
            high = middle
    if low < 0:
        raise SystemExit(f"AVIF makes no file of at most {size} bytes of this map")
    files = {level: avif(samples, level) for level in range(max(0, low - 3), min(100, low + 3) + 1)}
    level = max((lv for lv, data in files.items() if len(data) <= size), key=lambda lv: len(files[lv]))
    return files[level], level


def busiest_window(values: np.ndarray, side: int) -> tuple[int, int]:
    """Top-left corner of the ``side`` x ``side`` window of most gradient energy (stride side / 4)."""
    rows, cols = np.abs(np.diff(values, axis=0))[:, :-1], np.abs(np.diff(values, axis=1))[:-1, :]
    energy = np.sum(rows + cols, axis=-1)
    step = max(1, side // 4)
    corners = [
        (r, c)
        for r in range(0, energy.shape[0] - side + 1, step)
        for c in range(0, energy.shape[1] - side + 1, step)
    ]
    return max(corners, key=lambda rc: float(energy[rc[0] : rc[0] + side, rc[1] : rc[1] + side].sum()))


def figure(
    panels: list[tuple[str, np.ndarray]],
    errors: list[np.ndarray],
    note: str,
    corner: tuple[int, int],
    side: int,
    out: Path,
) -> None:
    """Write the crops of 8-bit RGB maps side by side (first row) and, under each decoded one, its
    angle to the original in degrees on one colour scale (second row, ``note`` beside it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    row, col = corner
    window = (slice(row, row + side), slice(col, col + side))
    fig, axes = plt.subplots(2, len(panels), figsize=(4.0 * len(panels), 8.6), layout="constrained")
    for ax, (title, samples) in zip(axes[0], panels, strict=True):
        ax.imshow(samples[window], interpolation="nearest")
        ax.set_title(title, fontsize=10)
    top = max(float(np.percentile(e[window], 99.5)) for e in errors)
    image = None
    for ax, error in zip(axes[1, 1:], errors, strict=True):
        image = ax.imshow(error[window], cmap="magma", vmin=0.0, vmax=top, interpolation="nearest")
        ax.set_title("angle to the original (degrees)", fontsize=10)
    axes[1, 0].axis("off")
    axes[1, 0].text(0.0, 0.5, note, fontsize=10, va="center", transform=axes[1, 0].transAxes)
    fig.colorbar(image, ax=axes[1, 1:], location="right", shrink=0.9, label="degrees")
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bpp", type=float, default=0.5, help="bandelets' rate target (default 0.5)")
    parser.add_argument("--crop", type=int, default=128, help="side of the crop in pixels (default 128)")
    parser.add_argument("--out", type=Path, default=Path("docs/crop-vs-avif.png"))
    args = parser.parse_args(argv)

    samples, name = load_source()
    source = to_values(samples)
    height, width = samples.shape[:2]
    ours = bandelets.encode(samples, bpp=args.bpp, kind="normal-map")
    our_samples = to_samples(bandelets.decode(ours))
    theirs, level = avif_not_above(samples, len(ours))
    their_samples = np.asarray(imagecodecs.avif_decode(theirs))[..., :3]

    rows = []
    for codec, data, decoded in (("bandelets", ours, our_samples), ("AVIF", theirs, their_samples)):
        value = psnr(source, to_values(decoded), "normal-map")
        rows.append((codec, len(data), 8 * len(data) / (height * width), value))
        print(f"{codec:9s} {len(data):6d} bytes  {rows[-1][2]:.3f} bpp  PSNR {value:.2f} dB")
    print(f"AVIF level {level} (4:4:4, identity, speed {AVIF_SPEED}): the largest file not above ours")

    corner = busiest_window(source, args.crop)
    (_, our_bytes, our_bpp, our_psnr), (_, their_bytes, their_bpp, their_psnr) = rows
    errors = [angles(source, to_values(d)).reshape(height, width) for d in (our_samples, their_samples)]
    note = "angle to the original,\nwhole map, degrees:\n\n" + "\n".join(
        f"{codec}: mean {np.mean(e):.2f}, p99 {np.percentile(e, 99):.2f}"
        for codec, e in zip(("bandelets", "AVIF"), errors, strict=True)
    )
    figure(
        [
            (f"original: {name}\ncrop {args.crop} x {args.crop} at {corner}", samples),
            (f"bandelets: {our_bytes} bytes ({our_bpp:.3f} bpp)\nPSNR {our_psnr:.2f} dB", our_samples),
            (
                f"AVIF level {level}: {their_bytes} bytes ({their_bpp:.3f} bpp)\nPSNR {their_psnr:.2f} dB",
                their_samples,
            ),
        ],
        errors,
        note,
        corner,
        args.crop,
        args.out,
    )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
