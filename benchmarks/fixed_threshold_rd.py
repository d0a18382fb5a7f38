"""Rate-distortion of two versions of the coder at the same thresholds, for changes of the coding.

    python benchmarks/fixed_threshold_rd.py --save old.json            # with one checkout on PYTHONPATH
    python benchmarks/fixed_threshold_rd.py --against old.json         # with the other

(from the repository root; about 2 minutes on the 2-core machine.) A change of the entropy
coder's contexts leaves the quantized coefficients almost as they were and only changes what
they cost, so the two coders are best compared at the same thresholds ``T``: with ``--save``,
the thresholds are those rate control picks for 0.25, 0.5, 1 and 2 bpp (``bandelets encode
--kind normal-map --bpp B``); with ``--against``, the saved ones. Each point is a real file,
decoded (restoration included); bpp is ``8 x bytes / pixels``, PSNR that of the renormalised
vectors. The maps: the generated ``crease`` and ``bumps`` maps (256 x 256, float), and the
shared real ``acacia_door_bottom_n`` (X and Y only: Z rebuilt, as ``rd_normal_maps.py``
does) and ``lava_flow_n`` maps of ``--maps`` (skipped when absent); ``--sizes 512`` adds
the generated maps at 512; ``--npy`` adds normal maps stored as float arrays (for instance the
mesh normal maps ``rd_surfaces.py`` writes to ``out/rd-benchmark/inputs/``; ``--sizes`` alone:
no generated map). Prints each map's points and, with ``--against``, the BD-PSNR of this coder
over the saved one (positive: this one better).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import bandelets
from bandelets.format.header import unpack
from bandelets.metrics import bd_psnr, bits_per_pixel, psnr
from bandelets.samples import bump_normal_map, crease_normal_map
from bandelets.transform.normals import unit_vectors

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_normal_maps import load  # noqa: E402

RATES = (0.25, 0.5, 1.0, 2.0)


def maps(folder: Path, sizes: list[int], arrays: list[Path]) -> dict:
    """Name -> (vectors, depth of the source: 0 float, 8 for the PNG maps)."""
    out = {path.stem: (np.load(path), 0) for path in arrays}
    for size in sizes:
        suffix = "" if size == 256 else f"@{size}"
        out[f"crease{suffix}"] = (crease_normal_map(size), 0)
        out[f"bumps{suffix}"] = (bump_normal_map(size), 0)
    for name in ("acacia_door_bottom_n", "lava_flow_n"):
        path = folder / f"{name}.png"
        if path.exists():
            out[name] = (load(path).astype(np.float64) / 255.0 * 2.0 - 1.0, 8)
        else:
            print(f"skipping {name}: {path} is absent (see --maps)")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    target = parser.add_mutually_exclusive_group(required=True)
    target.add_argument("--save", type=Path, help="write the points and thresholds here")
    target.add_argument("--against", type=Path, help="compare with the points saved here")
    parser.add_argument("--maps", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--sizes", type=int, nargs="*", default=[256])
    parser.add_argument("--npy", type=Path, nargs="*", default=[], help="more normal maps, float .npy")
    args = parser.parse_args()
    saved = json.loads(args.against.read_text()) if args.against else {}
    results = {}
    for name, (vectors, depth) in maps(args.maps, args.sizes, args.npy).items():
        if args.against and name not in saved:
            print(f"skipping {name}: not in {args.against}")
            continue
        points = []
        for i, rate in enumerate(RATES):
            if args.against:
                t = saved[name][i]["threshold"]
                data = bandelets.encode(vectors, threshold=t, kind="normal-map", depth=depth)
            else:
                data = bandelets.encode(vectors, bpp=rate, kind="normal-map", depth=depth)
                t = unpack(data)[0].threshold
            decoded = bandelets.decode(data)
            quality = psnr(unit_vectors(vectors), decoded, "normal-map")
            points.append({"threshold": t, "bpp": bits_per_pixel(len(data), vectors.shape), "psnr": quality})
        results[name] = points
        line = f"{name:22s} " + "  ".join(f"{p['bpp']:.3f} bpp {p['psnr']:.2f} dB" for p in points)
        if args.against:
            old = saved[name]
            gain = bd_psnr(
                [p["bpp"] for p in points],
                [p["psnr"] for p in points],
                [p["bpp"] for p in old],
                [p["psnr"] for p in old],
            )
            line += f"  BD-PSNR {gain:+.3f} dB"
        print(line, flush=True)
    if args.save:
        args.save.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
