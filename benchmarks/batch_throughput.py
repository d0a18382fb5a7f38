"""Throughput of ``bandelets batch`` on a local Dask cluster of 1 and of 2 worker processes.

Writes ``--maps`` generated normal maps of ``--size`` (mirrors and transposes of two bump maps
and of the crease map, 16-bit PNG) to a temporary folder, then for each worker count runs
:func:`bandelets.batch` on the folder into a fresh output folder. Each run makes its own
``LocalCluster``: its start, the workers' imports and numba cache loads are in the wall
time, as a user sees it. Prints per worker count the wall time, files per second, the
speedup over the first count, the sum of the per-file seconds (the time the workers spent on
files) and the load average (the machine may be shared: on a loaded machine two processes
also get a larger share of the cores than one, so the speedup is not the hardware's alone).
In the same run, for scale: OpenJPEG (imagecodecs.jpeg2k_encode, 16-bit, 9/7, one thread)
encoding the same maps one after the other, and the ratio of the batch's time per file to it.

    python benchmarks/batch_throughput.py [--maps 24] [--size 512] [--workers 1,2] [--threshold 0.02]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import imagecodecs
import numpy as np

import bandelets
from bandelets.samples import bump_normal_map, crease_normal_map


def _variant(normals: np.ndarray, i: int) -> np.ndarray:
    """The ``i``-th of the 8 mirrors and transposes of a normal map, its vectors turned with it."""
    if i & 1:
        normals = normals[:, ::-1] * [-1, 1, 1]
    if i & 2:
        normals = normals[::-1] * [1, -1, 1]
    if i & 4:
        normals = normals.transpose(1, 0, 2)[..., [1, 0, 2]]
    return normals


def _maps(folder: Path, count: int, size: int) -> list[np.ndarray]:
    """``count`` maps: the mirrors and transposes of two bump maps and of the crease map (a bump
    map takes seconds to generate)."""
    bases = [bump_normal_map(size, seed=0), bump_normal_map(size, seed=1), crease_normal_map(size)]
    pixels = []
    for i in range(count):
        normals = _variant(bases[i % 3], i // 3)
        pixels.append(np.ascontiguousarray(np.rint((normals + 1) / 2 * 65535), dtype=np.uint16))
        (folder / f"map{i:02d}.png").write_bytes(imagecodecs.png_encode(pixels[-1]))
    return pixels


def _openjpeg_seconds(pixels: list[np.ndarray]) -> float:
    start = time.perf_counter()
    for u16 in pixels:
        imagecodecs.jpeg2k_encode(u16, level=50, reversible=False, mct=False, codecformat="j2k")
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", type=int, default=24)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--workers", default="1,2", help="worker counts to compare (default 1,2)")
    target = parser.add_mutually_exclusive_group()
    target.add_argument(
        "--threshold", type=float, help="quantization threshold (default 0.02, about 0.2 to 0.6 bpp)"
    )
    target.add_argument("--bpp", type=float, help="target rate instead (rate control: slower)")
    args = parser.parse_args()
    target = {"bpp": args.bpp} if args.bpp is not None else {"threshold": args.threshold or 0.02}
    counts = [int(n) for n in args.workers.split(",")]

    with tempfile.TemporaryDirectory() as tmp:
        library = Path(tmp, "maps")
        library.mkdir()
        pixels = _maps(library, args.maps, args.size)
        openjpeg = _openjpeg_seconds(pixels)
        print(
            f"{args.maps} normal maps of {args.size} x {args.size}, {target}, {os.cpu_count()} cores",
            flush=True,
        )
        print(
            f"OpenJPEG, one process: {openjpeg:.2f} s ({openjpeg / args.maps * 1e3:.0f} ms per map)",
            flush=True,
        )
        print("workers  wall_s  files/s  speedup  file_s_sum  mean_bpp  load_before  load_after", flush=True)
        first = None
        for n in counts:
            load = os.getloadavg()[0]
            start = time.perf_counter()
            report = bandelets.batch([library], Path(tmp, f"out{n}"), kind="normal-map", **target, workers=n)
            wall = time.perf_counter() - start
            if (report.status != "ok").any():
                raise SystemExit(f"files failed: {report[report.status != 'ok'].error.tolist()}")
            if report.worker.nunique() != n:
                raise SystemExit(f"{n} workers asked, {report.worker.nunique()} did the work")
            first = first or wall
            figures = f"{n:7d}  {wall:6.1f}  {args.maps / wall:7.3f}  {first / wall:7.2f}  "
            figures += f"{report.seconds.sum():10.1f}  {report.bpp.mean():8.3f}  "
            print(f"{figures}{load:11.1f}  {os.getloadavg()[0]:10.1f}", flush=True)
            print(f"         batch wall time / OpenJPEG's (one process): {wall / openjpeg:.0f}x", flush=True)
        openjpeg = _openjpeg_seconds(pixels)
        print(f"OpenJPEG again after the runs: {openjpeg:.2f} s", flush=True)


if __name__ == "__main__":
    main()
