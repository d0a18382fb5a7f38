"""The rate-distortion benchmark of BENCHMARKS.md, in one command.

    python benchmarks/rd_surfaces.py [--size 256] [--out out/rd-benchmark]

(from the repository root; ``out/`` is ignored by git).

Runs ``bandelets rd`` three times on the surfaces the package generates:

1. normal maps, 0.25 to 2 bpp, every codec: the CAD-like crease map as floats and stored as
   8- and 16-bit PNG, and the smooth-bump map;
2. the paper's functional model (one channel: blurred curved step and tangent edges), every
   codec, at 1/32 to 1/4 bpp (at 0.25 to 2 bpp one channel is coded far beyond the 16-bit
   precision the anchors take, so those rates say nothing);
3. ``--decay`` on the functional model, bandelets and wavelets, 1/64 to 1 bpp.

Each run writes its files, rd.csv and rd.png under ``OUT/NAME/``; the printed tables are
collected in ``benchmarks/rd-results.md`` and the three plots copied to ``benchmarks/rd-*.png``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import shutil
import sys
import time
from pathlib import Path

from bandelets.cli import main
from bandelets.files import write_array
from bandelets.samples import crease_normal_map

HERE = Path(__file__).resolve().parent
NORMAL_RATES = "0.25,0.35,0.5,0.71,1,1.41,2"
MODEL_RATES = "0.03125,0.0442,0.0625,0.0884,0.125,0.177,0.25"


def _run(argv: list[str], log: io.StringIO) -> None:
    """Run the command line, echoing and keeping what it prints; stop on failure."""
    print(f"$ bandelets {' '.join(argv)}", file=log)
    started = time.perf_counter()
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        status = main(argv)
    print(printed.getvalue(), end="")
    print(printed.getvalue(), file=log)
    print(f"({time.perf_counter() - started:.0f} s)\n", file=log)
    if status:
        sys.exit(status)


def main_benchmark() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=256, help="side of the generated surfaces (default 256)")
    parser.add_argument(
        "--out", type=Path, default=Path("out/rd-benchmark"), help="folder of the runs (out/rd-benchmark)"
    )
    args = parser.parse_args()
    inputs = args.out / "inputs"
    inputs.mkdir(parents=True, exist_ok=True)
    normals = crease_normal_map(args.size)
    for depth in (8, 16):
        write_array(inputs / f"crease-{depth}bit.png", normals, "normal-map", depth)
    s = args.size
    log = io.StringIO()
    runs = {
        "normal-maps": [
            f"sample:crease@{s}",
            str(inputs / "crease-8bit.png"),
            str(inputs / "crease-16bit.png"),
            f"sample:bumps@{s}",
            "--kind",
            "normal-map",
            "--rates",
            NORMAL_RATES,
        ],
        "model": [f"sample:edge-step@{s}", f"sample:edge-tangent@{s}", "--rates", MODEL_RATES],
        "decay": [f"sample:edge-step@{s}", f"sample:edge-tangent@{s}", "--decay"],
    }
    for name, argv in runs.items():
        _run(["rd", *argv, "--out", str(args.out / name)], log)
        shutil.copyfile(args.out / name / "rd.png", HERE / f"rd-{name}.png")
    (HERE / "rd-results.md").write_text(log.getvalue())


if __name__ == "__main__":
    main_benchmark()
