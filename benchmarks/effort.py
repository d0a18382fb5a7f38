"""What the encoder's effort buys: encode CPU time, rate and PSNR of the decoded file at each effort.

    python benchmarks/effort.py [--rates 0.5,1,2] [--efforts 8,7,6,4] [--all]

The shared real 512 x 512 maps (``../shared/data/normal-maps/``, read as 8-bit samples as
``rd_defaults.py`` reads them; skipped with a message when absent; ``--all``: also the cobblestones,
the acacia door, the lava flow and the top-left 512 x 512 of the boombox) and the generated crease
and bevel maps, each
encoded with ``bandelets.encode(x, bpp=B, kind="normal-map", effort=E)`` after one warm-up encode, the
PSNR measured on the decoded file (BENCHMARKS.md, "Real maps, and the effort").
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import imagecodecs
import numpy as np

import bandelets
from bandelets.format.samples import from_samples
from bandelets.metrics import psnr
from bandelets.samples import bevel_normal_map, crease_normal_map

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "normal-maps"
REAL = {"vent decal 512": "godot_scifi_vent_decal_512.png", "leather cap 512": "flighthelmet_leather_512.png"}
MORE = {
    "cobblestones 1024": "learnwgpu_cobblestone_1024.png",
    "acacia door": "acacia_door_bottom_n.png",
    "lava flow": "lava_flow_n.png",
    "boombox 512 crop": "boombox_2048.png",
}


def maps(every: bool) -> dict[str, np.ndarray]:
    found = {}
    for name, file in (REAL | MORE if every else REAL).items():
        if (SHARED / file).exists():
            found[name] = imagecodecs.imread(SHARED / file)[..., :3]
            if name.endswith("crop"):
                found[name] = found[name][:512, :512]
        else:
            print(f"skipped {name}: {SHARED / file} is absent")
    found["crease 512"] = crease_normal_map(512)
    found["bevel 512"] = bevel_normal_map(512)
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", default="0.5,1,2")
    parser.add_argument("--efforts", default="8,7,6,4")
    parser.add_argument("--all", action="store_true", help="every shared map, not only the two 512 ones")
    args = parser.parse_args()
    rates = [float(r) for r in args.rates.split(",")]
    efforts = [int(e) for e in args.efforts.split(",")]
    for name, x in maps(args.all).items():
        reference = from_samples(x, "normal-map", 8) if x.dtype == np.uint8 else x
        bandelets.decode(bandelets.encode(x, bpp=1.0, kind="normal-map"))  # kernels loaded
        for bpp in rates:
            row = []
            for effort in efforts:
                start = time.process_time()
                data = bandelets.encode(x, bpp=bpp, kind="normal-map", effort=effort)
                seconds = time.process_time() - start
                quality = psnr(reference, bandelets.decode(data), "normal-map")
                rate = 8 * len(data) / (x.shape[0] * x.shape[1])
                row.append(f"effort {effort}: {seconds:.2f} s CPU, {rate:.3f} bpp, {quality:.2f} dB")
            print(f"{name} at {bpp:g} bpp: " + " | ".join(row), flush=True)


if __name__ == "__main__":
    main()
