"""Fit the Lagrangian's rate model to what the entropy coder really spends.

For a few thresholds, encode normal maps with bandelets and with wavelets (the x and y
channels, as the codec codes them), read the ideal code length of every coefficient from the
coder's ledger, and

* per class of square (the squares of the wavelet files, the NULL leaves and the bandelet
  leaves of the bandelet files) and per level: the bits per significant coefficient and per
  coefficient, and how far the current :data:`bandelets.search.lagrangian.RATE_MODEL` is from them;
* fit, per square, ``bits = a * log2 binomial + b * significant + c * sum log2 |m|`` by least
  squares, separately for wavelet squares and bandelet squares (the constants to paste into
  ``RATE_MODEL``);
* for every bandelet leaf, the bits the same region costs in the wavelet file at the same
  threshold: the extra bits the choice of a direction really costs, against what the model
  charges for it (what decides between NULL and a direction), by level and by width.

    python benchmarks/calibrate_rate.py [--size 256] [--transform-1d alpert2]
    python benchmarks/calibrate_rate.py --thresholds base.json   # its maps, at its thresholds

``--thresholds`` takes a file of ``benchmarks/fixed_threshold_rd.py --save`` (the thresholds
rate control picks at 0.25 to 2 bpp); without it, the generated crease map at four thresholds.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from bandelets.coding.image import code_image, new_coders
from bandelets.format.header import Header
from bandelets.format.quantizer import quantize
from bandelets.samples import crease_normal_map
from bandelets.search.basis import best_trees
from bandelets.search.lagrangian import RATE_MODEL, square_features
from bandelets.transform.bandeletize import bandeletize
from bandelets.transform.bandelets import apply_trees, wavelet_coefficients
from bandelets.transform.geometry import zigzag
from bandelets.transform.wavelets import max_levels, subband_slices

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fixed_threshold_rd import maps  # noqa: E402

#: Columns of a row: map, level, width, class (0 wavelet file, 1 NULL leaf, 2 bandelet leaf),
#: the square's features, its bits, then for a bandelet leaf the wavelet file's features and
#: bits of the same region.
CLASSES = ("wavelet file", "NULL leaves", "bandelet leaves")


def _code(coefficients, image, levels, t, transform, transform_1d):
    """Trees, transformed channels and each channel's ledger (bits per coefficient)."""
    header = Header(
        height=image.shape[0],
        width=image.shape[1],
        channels=image.shape[2],
        kind="normal-map",
        transform=transform,
        wavelet="cdf97",
        levels=levels,
        threshold=t,
        depth=0,
        transform_1d=transform_1d,
    )
    trees = best_trees(coefficients, levels, t, transform, transform_1d)
    bands = [apply_trees(c, levels, trees, bandeletize, transform_1d) for c in coefficients]
    _, _, spent = code_image(new_coders(), header, trees, [quantize(b, t).ravel() for b in bands])
    return trees, bands, [s.reshape(b.shape) for s, b in zip(spent, bands, strict=True)]


def collect(images: dict, thresholds: dict, transform_1d: str) -> np.ndarray:
    """One row per square of every channel (see :data:`CLASSES`)."""
    k = 2 if transform_1d == "alpert2" else 1
    rows = []
    for index, (name, image) in enumerate(images.items()):
        image = image[..., :2]  # z >= 0: the codec codes x and y only
        levels = max_levels(image.shape[:2])
        coefficients = wavelet_coefficients(image, "cdf97", levels)
        for t in thresholds[name]:
            _, wavelet, wavelet_bits = _code(coefficients, image, levels, t, "wavelet", transform_1d)
            trees, bandelet, bandelet_bits = _code(coefficients, image, levels, t, "bandelet", transform_1d)
            for w, wb, b, bb in zip(wavelet, wavelet_bits, bandelet, bandelet_bits, strict=True):
                for (level, _, where), tree in zip(subband_slices(b.shape, levels), trees, strict=True):
                    for r, c, width, d in zip(*tree.leaves(), strict=True):
                        sl = (
                            slice(where[0].start + r, where[0].start + r + width),
                            slice(where[1].start + c, where[1].start + c + width),
                        )
                        plain = (*square_features(w[sl].ravel(), t, 0)[:3], wb[sl].sum())
                        rows.append((index, level, width, 0, *plain, *plain))
                        if d >= 0:
                            own = square_features(b[sl].ravel()[zigzag(width)], t, k)[:3]
                        else:
                            own = square_features(b[sl].ravel(), t, 0)[:3]
                        rows.append((index, level, width, 1 + (d >= 0), *own, bb[sl].sum(), *plain))
    return np.array(rows)


def _modelled(features: np.ndarray, bandelet: bool) -> np.ndarray:
    return features @ RATE_MODEL[3:6] if bandelet else features @ RATE_MODEL[:3]


def report(rows: np.ndarray) -> None:
    print(
        f"{'class':16s} {'level':>5s} {'squares':>7s} {'signif.':>8s} {'bits':>9s} {'b/signif.':>9s} "
        f"{'b/coeff.':>8s} {'model/actual':>12s}"
    )
    for cls, name in enumerate(CLASSES):
        a = rows[rows[:, 3] == cls]
        for level in [0, *np.unique(a[:, 1]).astype(int)]:
            s = a if level == 0 else a[a[:, 1] == level]
            model = _modelled(s[:, 4:7], cls == 2).sum()
            bits = s[:, 7].sum()
            print(
                f"{name:16s} {level or 'all':>5} {len(s):7d} {s[:, 5].sum():8.0f} {bits:9.0f} "
                f"{bits / max(s[:, 5].sum(), 1):9.2f} {bits / np.sum(s[:, 2] ** 2):8.3f} {model / bits:12.3f}"
            )
    print("\nleast-squares fit per square, [a, b, c] (current in brackets):")
    for cls, base in ((0, 0), (2, 3)):
        a = rows[rows[:, 3] == cls]
        fit = np.linalg.lstsq(a[:, 4:7], a[:, 7], rcond=None)[0]
        print(f"  {CLASSES[cls]:16s} {np.round(fit, 3)} ({RATE_MODEL[base : base + 3]})")
    a = rows[rows[:, 3] == 2]
    extra = a[:, 7] - a[:, 11]
    charged = _modelled(a[:, 4:7], True) - _modelled(a[:, 8:11], False)
    print("\nbandelet leaves against the same regions in the wavelet file: extra bits, actual and modelled")
    for label, column in (("level", 1), ("width", 2)):
        for value in np.unique(a[:, column]).astype(int):
            m = a[:, column] == value
            print(
                f"  {label} {value:2d}: {m.sum():6d} leaves, significant {a[m, 5].sum():7.0f} "
                f"(wavelet file {a[m, 9].sum():7.0f}), extra bits {extra[m].sum():8.0f}, "
                f"modelled {charged[m].sum():8.0f}"
            )
    print(
        f"  all     : {len(a):6d} leaves, bits {a[:, 7].sum():.0f} against {a[:, 11].sum():.0f}, "
        f"extra {extra.sum():.0f}, modelled {charged.sum():.0f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--transform-1d", default="alpert2")
    parser.add_argument("--thresholds", type=Path, help="a fixed_threshold_rd.py --save file")
    parser.add_argument("--maps", type=Path, default=Path("../shared/data/normal-maps"))
    args = parser.parse_args()
    if args.thresholds is None:
        images = {"crease": crease_normal_map(args.size)}
        thresholds = {"crease": [0.04, 0.02, 0.01, 0.005]}
    else:
        saved = json.loads(args.thresholds.read_text())
        sizes = sorted({int(name.split("@")[1]) if "@" in name else 256 for name in saved})
        images = {name: v for name, (v, _) in maps(args.maps, sizes, []).items() if name in saved}
        thresholds = {name: [p["threshold"] for p in saved[name]] for name in images}
    for index, name in enumerate(images):
        print(f"map {index}: {name} at T = {', '.join(f'{t:.4g}' for t in thresholds[name])}")
    report(collect(images, thresholds, args.transform_1d))


if __name__ == "__main__":
    main()
