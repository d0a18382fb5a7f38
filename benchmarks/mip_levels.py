"""Mip levels from a prefix of a .bdl file (format version 19, issue 39): the bytes each level needs,
the angle of each level's image from a reference mip of the original, beside the mip of the full
decode and that of AVIF's decoded image at the same file size; and the speed of a level-2 decode.

    PYTHONPATH=src python benchmarks/mip_levels.py [--maps a.png,b.png] [--rates 0.5,1] [--size 512]
    PYTHONPATH=src python benchmarks/mip_levels.py --speed boombox_2048.png --rates 0.5

The reference mip of level k is the 2^k x 2^k box average of the original's unit vectors,
renormalised (:func:`bandelets.io.gpu.mip_chain`); every figure comes from the real files.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from bandelets import decode, encode
from bandelets.apps import anchors
from bandelets.codec.levels import level_bytes
from bandelets.io.gpu import mip_chain
from bandelets.metrics import angles
from bandelets.samples import bump_normal_map, crease_normal_map
from bandelets.transform.normals import unit_vectors

#: Shared maps whose blue is not z (BENCHMARKS.md: the acacia door's holds occlusion).
RG = ("acacia_door_bottom_n.png",)
DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "normal-maps"


def angle(a: np.ndarray, b: np.ndarray) -> float:
    h, w = min(a.shape[0], b.shape[0]), min(a.shape[1], b.shape[1])
    return float(angles(a[:h, :w], b[:h, :w]).mean())


def load(name: str, size: int) -> np.ndarray:
    if name == "bumps":
        return unit_vectors(bump_normal_map(size or 512))
    if name == "crease":
        return unit_vectors(crease_normal_map(size or 512))
    rgb = iio.imread(DATA / name)[..., :3].astype(np.float64)
    rgb = rgb / (65535 if rgb.max() > 255 else 255) * 2 - 1
    if name in RG:  # its blue holds occlusion: x, y are red and green, z rebuilt
        rgb = rgb[..., :2]
    return unit_vectors(rgb if not size else rgb[:size, :size])


def table(names: list[str], rates: list[float], size: int) -> None:
    print(
        "| map | bpp | bytes | level | bytes needed | % of file "
        "| angle to ref mip: level image | full-decode mip | AVIF mip |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in names:
        x = load(name, size)
        reference = mip_chain(x)
        for bpp in rates:
            data = encode(x, bpp=bpp, kind="normal-map")
            needs = level_bytes(data)
            full = mip_chain(decode(data))
            rate = 8 * len(data) / x.shape[0] / x.shape[1]
            try:
                avif = anchors.encode(x, rate, "avif", "normal-map", 8)
                avif = mip_chain(anchors.decode(avif, "avif", x, "normal-map", 8))
            except ValueError:  # AVIF cannot reach so few bytes on a small map
                avif = None
            for k in range(1, len(needs)):
                image = decode(data[: needs[k]], level=k)
                print(
                    f"| {name} | {bpp} | {len(data)} | {k} | {needs[k]} | {100 * needs[k] / len(data):.1f} | "
                    f"{angle(image, reference[k]):.2f} | {angle(full[k], reference[k]):.2f} | "
                    f"{'n/a' if avif is None else f'{angle(avif[k], reference[k]):.2f}'} |",
                    flush=True,
                )


def speed(name: str, rate: float) -> None:
    x = load(name, 0)
    data = encode(x, bpp=rate, kind="normal-map")
    needs = level_bytes(data)
    times = {}
    for k in (0, 2):
        start = time.perf_counter()
        decode(data, level=k) if k else decode(data)
        times[k] = time.perf_counter() - start
    print(
        f"{name} at {rate} bpp: {len(data)} bytes; level 2 needs {needs[2]} ({needs[2] / len(data):.1%}); "
        f"full decode {times[0]:.2f} s, level 2 {times[2]:.2f} s ({times[2] / times[0]:.1%})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--maps", default="flighthelmet_leather_512.png,godot_scifi_vent_decal_512.png,bumps,crease"
    )
    parser.add_argument("--rates", default="0.5,1")
    parser.add_argument(
        "--size", type=int, default=512, help="crop of the real maps (0: whole), side of generated"
    )
    parser.add_argument(
        "--speed", help="only time a level-2 decode of this shared map, against the full decode"
    )
    args = parser.parse_args()
    rates = [float(r) for r in args.rates.split(",")]
    if args.speed:
        for rate in rates:
            speed(args.speed, rate)
        return
    table(args.maps.split(","), rates, args.size)


if __name__ == "__main__":
    main()
