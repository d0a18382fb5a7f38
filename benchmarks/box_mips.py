"""Box mips from a prefix (issue 39): with ``encode(box_mips=True)`` the level-k image of a prefix of
the file should be within 0.1 degree of the box mip of the full decode, both measured against the
reference mip of the original; and what the option costs in rate against the default encoding.

    PYTHONPATH=src python benchmarks/box_mips.py [--maps a.png,bumps] [--rates 0.5,1] \
        [--bd-rates 0.25,0.5,1,2] [--wavelets rbio1.3,haar] [--size 512] [--only levels|cost|floors]

First table: for each map, rate and box wavelet, the mean angle (degrees) of each level's prefix
image and of the full decode's mip from the reference mip (the 2^k x 2^k box average of the
original's unit vectors, renormalised: :func:`bandelets.io.gpu.mip_chain`), and the largest excess
of the first over the second. Second table: BD-PSNR (the normal-map PSNR of
:func:`bandelets.metrics.psnr`, from the decoded files) of each box wavelet over the default file,
and the mean angle at each rate of ``--bd-rates``. Every bpp is 8 x file bytes / pixels.
"""

from __future__ import annotations

import argparse

import numpy as np
from mip_levels import angle, load

from bandelets import decode, encode
from bandelets.codec.levels import level_bytes
from bandelets.io.gpu import mip_chain
from bandelets.metrics import bd_psnr, psnr
from bandelets.transform.normals import equidistant

MAPS = (
    "acacia_door_bottom_n.png,boombox_2048.png,flighthelmet_leather_512.png,godot_scifi_vent_decal_512.png,"
    "lava_flow_n.png,learnwgpu_cobblestone_1024.png,bumps,crease"
)


def point(x: np.ndarray, rate: float, wavelet: str | None) -> tuple[bytes, np.ndarray]:
    """The file of ``x`` at ``rate`` (box mips with ``wavelet``, or the default encoding) and its decode."""
    options = {"box_mips": True, "wavelet": wavelet} if wavelet else {}
    data = encode(x, bpp=rate, kind="normal-map", **options)
    return data, decode(data)


def level_table(names: list[str], rates: list[float], wavelets: list[str], size: int) -> None:
    print("| map | bpp | wavelet | level image / full-decode mip, levels 1, 2, ... (degrees) | worst |")
    print("| --- | --- | --- | --- | --- |")
    for name in names:
        x = load(name, size)
        reference = mip_chain(x)
        for rate in rates:
            for wavelet in wavelets:
                data, full = point(x, rate, wavelet)
                mips, needs = mip_chain(full), level_bytes(data)
                pairs = [
                    (angle(decode(data[: needs[k]], level=k), reference[k]), angle(mips[k], reference[k]))
                    for k in range(1, len(needs))
                ]
                cells = ", ".join(f"{a:.2f} / {b:.2f}" for a, b in pairs)
                worst = max(a - b for a, b in pairs)
                bpp = 8 * len(data) / x.shape[0] / x.shape[1]
                print(f"| {name} | {bpp:.3f} | {wavelet} | {cells} | {worst:+.3f} |", flush=True)


def cost_table(names: list[str], rates: list[float], wavelets: list[str], size: int) -> None:
    print()
    print(
        f"| map | BD-PSNR of box mips over the default, dB ({', '.join(wavelets)}) "
        f"| mean angle at {', '.join(map(str, rates))} bpp: default / {' / '.join(wavelets)} |"
    )
    print("| --- | --- | --- |")
    for name in names:
        x = load(name, size)
        curves = {}
        for wavelet in (None, *wavelets):
            points = []
            for rate in rates:
                data, full = point(x, rate, wavelet)
                bpp = 8 * len(data) / x.shape[0] / x.shape[1]
                points.append((bpp, psnr(x, full, "normal-map"), angle(full, x)))
            curves[wavelet] = np.array(points)
        base = curves[None]
        boxes = list(curves.values())[1:]
        bd = ", ".join(f"{bd_psnr(c[:, 0], c[:, 1], base[:, 0], base[:, 1]):+.2f}" for c in boxes)
        angles = ", ".join(" / ".join(f"{c[i, 2]:.2f}" for c in curves.values()) for i in range(len(rates)))
        print(f"| {name} | {bd} | {angles} |", flush=True)


def box(a: np.ndarray, k: int) -> np.ndarray:
    h, w = a.shape[0] >> k, a.shape[1] >> k
    return a[: h << k, : w << k].reshape(h, 1 << k, w, 1 << k, -1).mean(axis=(1, 3))


def floor_table(names: list[str], size: int) -> None:
    """Why two channels cannot give box mips: the mean angle of the box average of each map's
    equidistant coordinates / of its x, y (z rebuilt) from the reference mip, before any coding."""
    print("| map | equidistant / x, y: levels 1, 2, ... (degrees) |")
    print("| --- | --- |")
    for name in names:
        x = load(name, size)
        reference, coordinates = mip_chain(x), equidistant(x)
        cells = []
        for k in range(1, len(reference)):
            if min(reference[k].shape[:2]) < 2:
                break
            eq = box(coordinates, k)
            angle_to_z = np.linalg.norm(eq, axis=-1, keepdims=True)
            shrink = np.sin(angle_to_z) / np.maximum(angle_to_z, 1e-300)
            vectors = np.dstack([eq * np.where(angle_to_z > 0, shrink, 1.0), np.cos(angle_to_z)])
            xy = np.clip(box(x[..., :2], k), -1, 1)
            cells.append(f"{angle(vectors, reference[k]):.2f} / {angle(xy, reference[k]):.2f}")
        print(f"| {name} | {', '.join(cells)} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", default=MAPS)
    parser.add_argument("--rates", default="0.5,1")
    parser.add_argument("--bd-rates", default="0.25,0.5,1,2")
    parser.add_argument("--wavelets", default="rbio1.3,haar")
    parser.add_argument(
        "--size", type=int, default=512, help="crop of the real maps (0: whole), generated side"
    )
    parser.add_argument("--only", choices=("levels", "cost", "floors"), help="one table (floors: only so)")
    args = parser.parse_args()
    names, wavelets = args.maps.split(","), args.wavelets.split(",")
    if args.only == "floors":
        floor_table(names, args.size)
        return
    if args.only != "cost":
        level_table(names, [float(r) for r in args.rates.split(",")], wavelets, args.size)
    if args.only != "levels":
        cost_table(names, [float(r) for r in args.bd_rates.split(",")], wavelets, args.size)


if __name__ == "__main__":
    main()
