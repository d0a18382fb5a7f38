"""What coding in tiles costs (:mod:`bandelets.codec.tiles`): PSNR of the tiled and the untiled coder at
the same rates, on generated normal maps, and the error along the tile borders.

For each map and target rate: the bpp and PSNR of the tiled file (default tiles) and of the
untiled one (one tile), their difference in dB, and the RMS error of the pixels within 2 of a
tile border against that of the other pixels, for both files (the untiled file's ratio is the
control: a seam shows as a tiled ratio above it). With ``--out``, the error maps (x 20, gray)
around the centre of the tiled and untiled decodes are written as PNGs to look at.

``--same-threshold`` codes both files at the threshold of the untiled one at each rate: what
tiling costs in rate, the error being nearly the same.

    python benchmarks/tiling_cost.py [--size 1024] [--rates 0.25,1] [--tile 512] [--out DIR]
        [--same-threshold]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import imagecodecs
import numpy as np

import bandelets
from bandelets.codec.encoder import encode_with_stats
from bandelets.codec.options import EncodeOptions
from bandelets.format.container import cuts
from bandelets.metrics import bits_per_pixel, psnr
from bandelets.samples import bump_normal_map, crease_normal_map


def _border_mask(size: int, tile: int, width: int = 2) -> np.ndarray:
    """Pixels within ``width`` of a border between two tiles."""
    near = np.zeros(size, bool)
    for span in cuts(size, tile)[1:]:
        near[max(span.start - width, 0) : span.start + width] = True
    return near[:, None] | near[None, :]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--rates", default="0.25,1")
    parser.add_argument("--tile", type=int, default=512)
    parser.add_argument("--out", help="folder for the error maps around the centre")
    parser.add_argument(
        "--same-threshold",
        action="store_true",
        help="code both at the threshold of the untiled file of each rate (the tiled bpp is then the cost)",
    )
    args = parser.parse_args()
    border = _border_mask(args.size, args.tile)
    print(
        f"{'map':>7} {'bpp':>5} {'tiled bpp':>9} {'dB':>7} {'untiled bpp':>11} {'dB':>7} {'cost dB':>7} "
        f"{'border/inside RMS tiled':>23} {'untiled':>7}"
    )
    for name, normals in (("crease", crease_normal_map(args.size)), ("bumps", bump_normal_map(args.size))):
        for rate in (float(r) for r in args.rates.split(",")):
            row, ratios = [], []
            target = dict(bpp=rate)
            if args.same_threshold:
                untiled = EncodeOptions(kind="normal-map", tile=2 * args.size)
                target = dict(threshold=encode_with_stats(normals, untiled, bpp=rate).threshold)
            for tile in (args.tile, 2 * args.size):
                data = bandelets.encode(normals, kind="normal-map", tile=tile, **target)
                decoded = bandelets.decode(data)
                error = np.sqrt(np.sum((decoded - normals) ** 2, axis=-1))
                ratios.append(np.sqrt(np.mean(error[border] ** 2) / np.mean(error[~border] ** 2)))
                row.append((bits_per_pixel(len(data), normals.shape), psnr(normals, decoded, "normal-map")))
                if args.out:
                    centre = slice(args.size // 2 - 64, args.size // 2 + 64)
                    crop = np.clip(error[centre, centre] * 20 * 255, 0, 255).astype(np.uint8)
                    label = "tiled" if tile == args.tile else "untiled"
                    path = Path(args.out) / f"error-{name}-{rate:g}bpp-{label}.png"
                    path.parent.mkdir(parents=True, exist_ok=True)
                    path.write_bytes(imagecodecs.png_encode(crop))
            (tb, tp), (ub, up) = row
            print(
                f"{name:>7} {rate:>5g} {tb:>9.3f} {tp:>7.2f} {ub:>11.3f} {up:>7.2f} {tp - up:>+7.2f} "
                f"{ratios[0]:>23.2f} {ratios[1]:>7.2f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
