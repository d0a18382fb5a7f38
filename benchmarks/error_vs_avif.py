"""Where bandelets' error is against AVIF's at the same rate, on one normal map.

    python benchmarks/error_vs_avif.py [MAP] [--bpp 0.5] [--lifting]

(from the repository root, a few seconds; MAP: a PNG normal map, default the generated
256 x 256 crease map.) Encodes the map with the defaults (``bandelets.encode(kind="normal-map",
bpp=B)``, with ``lifting=True`` if asked) and with AVIF as :mod:`bandelets.apps.anchors` drives it,
both decoded from their files, and prints their squared error summed near the creases (within
two pixels of the 10 % largest gradients) and elsewhere, then the error of each wavelet level
(the error images put through the CDF 9/7 analysis, x and y channels), as the ratio ours /
AVIF's.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import ndimage

import bandelets
from bandelets.apps import anchors
from bandelets.io.files import read_array
from bandelets.metrics import bits_per_pixel, psnr
from bandelets.samples import crease_normal_map
from bandelets.transform.normals import unit_vectors
from bandelets.transform.wavelets import max_levels, subband_slices, wavedec


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("map", nargs="?", help="PNG normal map (default: the generated crease map, 256)")
    parser.add_argument("--bpp", type=float, default=0.5)
    parser.add_argument("--lifting", action="store_true", help="lift the finest levels along directions")
    args = parser.parse_args()
    x, depth = read_array(args.map, "normal-map") if args.map else (crease_normal_map(256), 0)
    x = unit_vectors(x)
    ours = bandelets.encode(x, bpp=args.bpp, kind="normal-map", depth=depth, lifting=args.lifting)
    avif = anchors.encode(x, args.bpp, "avif", "normal-map", depth)
    errors = {
        "ours": bandelets.decode(ours) - x,
        "AVIF": anchors.decode(avif, "avif", x, "normal-map", depth) - x,
    }
    for name, data in (("ours", ours), ("AVIF", avif)):
        rate = bits_per_pixel(len(data), x.shape)
        print(f"{name}: {rate:.3f} bpp, {psnr(x, errors[name] + x, 'normal-map'):.2f} dB")
    gradient = sum(np.hypot(ndimage.sobel(x[..., k], 0), ndimage.sobel(x[..., k], 1)) for k in range(3))
    near = ndimage.binary_dilation(gradient > np.percentile(gradient, 90), iterations=2)
    for label, where in (("near creases", near), ("elsewhere", ~near)):
        ratio = np.sum(errors["ours"][where] ** 2) / np.sum(errors["AVIF"][where] ** 2)
        print(f"{label} ({where.mean():.0%} of the pixels): error ours / AVIF {ratio:.2f}")
    levels = max_levels(x.shape[:2])
    side = (x.shape[0] >> levels, x.shape[1] >> levels)
    for k in range(2):
        c = {name: wavedec(e[..., k], "cdf97", levels) for name, e in errors.items()}
        low = {name: np.sum(v[: side[0], : side[1]] ** 2) for name, v in c.items()}
        cells = [f"approximation {low['ours'] / low['AVIF']:.2f}"]
        for level in range(levels, 0, -1):
            bands = [where for lev, _, where in subband_slices(x.shape[:2], levels) if lev == level]
            energy = {name: sum(np.sum(v[w] ** 2) for w in bands) for name, v in c.items()}
            share = energy["ours"] / np.sum(c["ours"] ** 2)
            cells.append(f"level {level} {energy['ours'] / energy['AVIF']:.2f} ({share:.0%} of ours)")
        print(f"channel {'xy'[k]}, error ours / AVIF by level:", ", ".join(cells))


if __name__ == "__main__":
    main()
