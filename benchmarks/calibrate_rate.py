"""Fit the Lagrangian's rate model to what the entropy coder really spends.

For a few thresholds, encode the generated crease normal map with bandelets and with
wavelets, read the ideal code length of every coefficient from the coder's ledger, and
fit, per square, ``bits = a * log2 binomial + b * significant + c * sum log2 |m|`` by least
squares, separately for wavelet squares and bandelet squares. Prints the fitted constants
(to paste into ``bandelets.lagrangian.RATE_MODEL``) and how well the current ones track the
real bits.

    python benchmarks/calibrate_rate.py [--size 256] [--transform-1d alpert2]
"""

from __future__ import annotations

import argparse

import numpy as np

from bandelets.bandeletize import bandeletize
from bandelets.bitstream import Header
from bandelets.coding import code_image, new_coders
from bandelets.geometry import zigzag
from bandelets.lagrangian import RATE_MODEL, square_features
from bandelets.quantize import quantize
from bandelets.samples import crease_normal_map
from bandelets.transform import apply_trees, best_trees, wavelet_coefficients
from bandelets.wavelets import max_levels, subband_slices


def collect(size: int, transform_1d: str, thresholds: list[float]):
    """Rows (significance, significant, sum log2 m, actual bits) for wavelet / bandelet squares."""
    image = crease_normal_map(size)[..., :2]  # z >= 0: the codec codes x and y only
    levels = max_levels(image.shape[:2])
    coefficients = wavelet_coefficients(image, "cdf97", levels)
    k = 2 if transform_1d == "alpert2" else 1
    rows = {"wavelet": [], "bandelet": []}
    for t in thresholds:
        for transform in ("wavelet", "bandelet"):
            header = Header(
                height=size,
                width=size,
                channels=2,
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
            for b, ledger in zip(bands, spent, strict=True):
                ledger = ledger.reshape(b.shape)
                for (_, _, where), tree in zip(subband_slices(b.shape, levels), trees, strict=True):
                    for r, col, w, d in zip(*tree.leaves(), strict=True):
                        if (d >= 0) != (transform == "bandelet"):
                            continue
                        sl = (
                            slice(where[0].start + r, where[0].start + r + w),
                            slice(where[1].start + col, where[1].start + col + w),
                        )
                        values = b[sl].ravel()[zigzag(w)] if d >= 0 else b[sl].ravel()
                        features = square_features(values, t, k if d >= 0 else 0)[:3]
                        rows[transform].append((*features, ledger[sl].sum()))
    return {name: np.array(r) for name, r in rows.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--transform-1d", default="alpert2")
    args = parser.parse_args()
    data = collect(args.size, args.transform_1d, [0.04, 0.02, 0.01, 0.005])
    for index, name in enumerate(("wavelet", "bandelet")):
        a = data[name]
        fit = np.linalg.lstsq(a[:, :3], a[:, 3], rcond=None)[0]
        current = a[:, :3] @ RATE_MODEL[3 * index : 3 * index + 3]
        print(
            f"{name:9s} squares {len(a):6d}  fitted {np.round(fit, 3)}  actual bits {a[:, 3].sum():9.0f}  "
            f"current model {current.sum():9.0f} ({current.sum() / a[:, 3].sum() - 1:+.1%})  "
            f"per-square error {np.abs(current - a[:, 3]).sum() / a[:, 3].sum():.1%}"
        )


if __name__ == "__main__":
    main()
