"""File sizes at fixed thresholds and the entropy decoder's time: one build against another.

    python benchmarks/mixed_contexts.py                        # this build
    PYTHONPATH=OTHER/src python benchmarks/mixed_contexts.py   # another checkout (OTHER), e.g. a
                                                               # git worktree of an earlier commit

(from the repository root; about a minute.) At a fixed threshold the quantized coefficients are
the same whatever the entropy coder (but for the encoder's rate-distortion optimised choice
between 0 and 1, which prices them with the coder), so the bytes of the same map at the same
threshold compare two coders. Prints, for the fandisk rendered from the top (16-bit samples, as
``rd_normal_maps.py --rendered`` makes it), the normal map of the fandisk mesh (floats), and the
generated crease and bevel maps at 256 x 256, the bytes of ``bandelets.encode(map,
threshold=T, kind="normal-map", depth=D)`` at four thresholds each, and the median wall time of
``bandelets.decode(data, restore=False)`` (``--repeat`` runs) of the 512 x 512 crease map at 1
bpp, the standing speed file: there the coefficient decoding is most of what differs.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import bandelets
from bandelets.samples import crease_normal_map

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_defaults import _maps  # noqa: E402

#: Thresholds of each map: its files of about 0.25, 0.35, 0.5 and 1 bpp.
THRESHOLDS = {
    "fandisk-top@256": (0.15, 0.1, 0.04, 0.01),
    "fandisk": (0.4, 0.17, 0.07, 0.025),
    "crease@256": (0.2, 0.09, 0.035, 0.008),
    "bevel@256": (0.5, 0.3, 0.15, 0.06),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--real", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--meshes", type=Path, default=Path("../shared/data/meshes"))
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args()
    print(f"bandelets from {Path(bandelets.__file__).parent}")
    for name, (vectors, depth) in _maps(THRESHOLDS, args.real, args.meshes):
        points = []
        for t in THRESHOLDS[name]:
            size = len(bandelets.encode(vectors, threshold=t, kind="normal-map", depth=depth))
            points.append(f"T {t:g}: {size} bytes")
        print(f"{name}: " + ", ".join(points))
    data = bandelets.encode(crease_normal_map(512), bpp=1.0, kind="normal-map")
    bandelets.decode(data, restore=False)
    times = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        bandelets.decode(data, restore=False)
        times.append(time.perf_counter() - start)
    median = 1e3 * statistics.median(times)
    print(f"crease 512 at 1 bpp ({len(data)} bytes): decode without restoration {median:.1f} ms")


if __name__ == "__main__":
    main()
