"""Lossless files: the rate of ``bandelets encode --lossless`` against every anchor's lossless
mode, and its time against OpenJPEG's.

    python benchmarks/lossless.py [--maps ../shared/data/normal-maps]

(from the repository root; about a minute.) The maps: the shared real normal maps as their PNG
holds them (the acacia door's blue is its ambient occlusion), and the generated crease and bumps
maps (:mod:`bandelets.samples`) as 8 and 16-bit samples at 256 and 512. Each file is decoded and
checked against its samples (:func:`bandelets.apps.anchors.encode_lossless` checks the anchors'). AVIF
takes at most 12 bits: no 16-bit entry. Times: the median of three runs, encoding and decoding
in memory, OpenJPEG's reversible encoding of the same samples timed in the same run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import imagecodecs
import numpy as np

import bandelets
from bandelets.apps import anchors
from bandelets.format.samples import from_samples, to_samples
from bandelets.samples import bump_normal_map, crease_normal_map

CODECS = ("jpegxl", "avif", "jpeg2000")


def _median_time(function, runs: int = 3) -> tuple[float, object]:
    times, out = [], None
    for _ in range(runs):
        start = time.perf_counter()
        out = function()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--maps", type=Path, default=Path("../shared/data/normal-maps"))
    args = parser.parse_args()
    maps = {}
    for path in sorted(args.maps.glob("*.png")) if args.maps.is_dir() else []:
        maps[path.stem] = imagecodecs.png_decode(path.read_bytes())[..., :3]
    for size in (256, 512):
        for name, make in (("crease", crease_normal_map), ("bumps", bump_normal_map)):
            vectors = make(size)
            for depth in (8, 16):
                maps[f"{name}@{size} {depth}-bit"] = to_samples(vectors, "normal-map", depth)
    bandelets.encode(maps[next(iter(maps))], kind="normal-map", lossless=True)  # compile
    print("| map | bandelets | " + " | ".join(CODECS) + " | png | encode s | decode s | OpenJPEG encode s |")
    print("| --- |" + " --- |" * (len(CODECS) + 5))
    for name, samples in maps.items():
        depth = 8 if samples.dtype == np.uint8 else 16
        pixels = samples.shape[0] * samples.shape[1]
        encode_s, data = _median_time(lambda s=samples: bandelets.encode(s, kind="normal-map", lossless=True))
        decode_s, decoded = _median_time(lambda d=data: bandelets.decode(d))
        if not np.array_equal(decoded, from_samples(samples, "normal-map", depth)):
            raise RuntimeError(f"{name}: the lossless file does not decode to its samples")
        cells = [f"{8 * len(data) / pixels:.3f}"]
        for codec in CODECS:
            if codec == "avif" and depth == 16:
                cells.append("-")
                continue
            cells.append(f"{8 * len(anchors.encode_lossless(samples, codec)) / pixels:.3f}")
        cells.append(f"{8 * len(imagecodecs.png_encode(samples, level=9)) / pixels:.3f}")
        openjpeg_s, _ = _median_time(
            lambda s=samples: imagecodecs.jpeg2k_encode(
                s, level=0, codecformat="J2K", reversible=True, mct=False
            )
        )
        cells += [f"{encode_s:.3f}", f"{decode_s:.3f}", f"{openjpeg_s:.3f}"]
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
