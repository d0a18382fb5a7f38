"""The rate-distortion benchmark of BENCHMARKS.md, in one command.

    python benchmarks/rd_surfaces.py [--size 256] [--out out/rd-benchmark] [--results benchmarks]

(from the repository root; ``out/`` is ignored by git).

Runs ``bandelets rd`` four times, on the surfaces the package generates and on two meshes:

1. normal maps, 0.25 to 2 bpp, every codec: the CAD-like crease map as floats and stored as
   8- and 16-bit PNG, and the smooth-bump map;
2. the paper's functional model (one channel: blurred curved step and tangent edges), every
   codec, at 1/32 to 1/4 bpp (at 0.25 to 2 bpp one channel is coded far beyond the 16-bit
   precision the anchors take, so those rates say nothing);
3. ``--decay`` on the functional model, bandelets and wavelets, 1/64 to 1 bpp;
4. normal maps of two shared meshes, every codec, 0.25 to 2 bpp: ``fandisk`` (CAD, creases)
   and ``bunny`` (scanned), the unit normals of their spherical geometry images
   (``bandelets geometry-image MESH OUT.npy --normals NORMALS.npy``), skipped with a message
   when ``--meshes`` (default ``../shared/data/meshes``) does not hold them.

Each run writes its files, rd.csv and rd.png under ``OUT/NAME/``; the printed tables are
collected in ``benchmarks/rd-results.md`` (one ``## NAME`` section per run) and the plots
copied to ``benchmarks/rd-NAME.png``; ``--results DIR`` puts those two elsewhere (a scratch run
that should not touch the checkout's results). ``--only NAME ...`` reruns some runs and replaces just
their sections. With a ``--size`` other than 256 the runs are named ``NAME-SIZE`` (for
instance ``normal-maps-512``, the paper's resolution), so they sit beside the default ones.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import shutil
import sys
import time
from pathlib import Path

from bandelets.apps.cli import main
from bandelets.io.files import write_array
from bandelets.samples import crease_normal_map
from bandelets.surfaces.codec import load_mesh, make_geometry_image

HERE = Path(__file__).resolve().parent
NORMAL_RATES = "0.25,0.35,0.5,0.71,1,1.41,2"
MODEL_RATES = "0.03125,0.0442,0.0625,0.0884,0.125,0.177,0.25"
MESH_NORMAL_RATES = "0.25,0.5,1,2"
MESHES = ("fandisk.off", "bunny.off")
RUNS = ("normal-maps", "model", "decay", "mesh-normals")
DEFAULT_SIZE = 256


def _run(argv: list[str]) -> str:
    """Run the command line, echoing what it prints; return the log; stop on failure."""
    log = io.StringIO()
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
    return log.getvalue()


def _mesh_normal_maps(meshes: Path, size: int, inputs: Path) -> list[str]:
    """Write the normal maps of :data:`MESHES` as float32 .npy; return their paths ([] if absent)."""
    missing = [name for name in MESHES if not (meshes / name).is_file()]
    if missing:
        print(f"skipping the mesh normal maps: {', '.join(missing)} not in {meshes} (see --meshes)\n")
        return []
    paths = []
    for name in MESHES:
        path = inputs / f"{Path(name).stem}-normals.npy"
        write_array(path, make_geometry_image(load_mesh(meshes / name), size).normals, "normal-map", 16)
        paths.append(str(path))
    return paths


def _store(results: Path, name: str, text: str) -> None:
    """Replace the ``## name`` section of ``results`` by ``text``, or append it."""
    old = results.read_text() if results.is_file() else ""
    heading = f"## {name}\n"
    start = old.find(heading)
    if start < 0:
        results.write_text(old + heading + text)
        return
    end = old.find("\n## ", start + len(heading))
    results.write_text(old[:start] + heading + text + ("" if end < 0 else old[end + 1 :]))


def main_benchmark() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--size", type=int, default=DEFAULT_SIZE, help=f"side of the generated maps (default {DEFAULT_SIZE})"
    )
    parser.add_argument(
        "--out", type=Path, default=Path("out/rd-benchmark"), help="folder of the runs (out/rd-benchmark)"
    )
    parser.add_argument(
        "--meshes",
        type=Path,
        default=Path("../shared/data/meshes"),
        help="folder of fandisk.off and bunny.off (../shared/data/meshes)",
    )
    parser.add_argument(
        "--results", type=Path, default=HERE, help="folder of rd-results.md and the plots (benchmarks/)"
    )
    parser.add_argument("--only", nargs="+", choices=RUNS, default=RUNS, help="runs to redo (default all)")
    args = parser.parse_args()
    inputs = args.out / "inputs"
    inputs.mkdir(parents=True, exist_ok=True)
    s = args.size
    runs = {}
    if "normal-maps" in args.only:
        normals = crease_normal_map(s)
        for depth in (8, 16):
            write_array(inputs / f"crease-{depth}bit.png", normals, "normal-map", depth)
        runs["normal-maps"] = [
            f"sample:crease@{s}",
            str(inputs / "crease-8bit.png"),
            str(inputs / "crease-16bit.png"),
            f"sample:bumps@{s}",
            "--kind",
            "normal-map",
            "--rates",
            NORMAL_RATES,
        ]
    if "model" in args.only:
        runs["model"] = [f"sample:edge-step@{s}", f"sample:edge-tangent@{s}", "--rates", MODEL_RATES]
    if "decay" in args.only:
        runs["decay"] = [f"sample:edge-step@{s}", f"sample:edge-tangent@{s}", "--decay"]
    if "mesh-normals" in args.only and (paths := _mesh_normal_maps(args.meshes, s, inputs)):
        runs["mesh-normals"] = [*paths, "--kind", "normal-map", "--rates", MESH_NORMAL_RATES]
    args.results.mkdir(parents=True, exist_ok=True)
    results = args.results / "rd-results.md"
    for name, argv in runs.items():
        name = name if s == DEFAULT_SIZE else f"{name}-{s}"
        _store(results, name, _run(["rd", *argv, "--out", str(args.out / name)]))
        shutil.copyfile(args.out / name / "rd.png", args.results / f"rd-{name}.png")


if __name__ == "__main__":
    main_benchmark()
