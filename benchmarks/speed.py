"""Speed of the codec beside OpenJPEG and AVIF, on the same image, in one run.

For a generated crease normal map of each size: the median over ``--repeat`` runs of
bandelet encode at 1 bpp (rate control included), encode at a fixed threshold, and decode,
with OpenJPEG (JPEG2000, 16-bit) and libavif (12-bit, speed 6) encode and decode times on
the same map through imagecodecs, and the ratios; also the process CPU time of the bandelet
runs (all threads: less sensitive to other load on the machine than wall time). Before that,
the cold start: import, compilation of every numba kernel (empty cache) and a small encode.
Then the time per pixel against the 512 x 512 one, and the peak resident memory of a
2048 x 2048 x 3 bandelet encode (in a child process whose high-water mark is reset after the
map is generated, Linux only).

    python benchmarks/speed.py [--sizes 256,512,1024,2048] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from functools import partial

import imagecodecs
import numpy as np

import bandelets
from bandelets.samples import crease_normal_map


def _median_seconds(run, repeat: int, cpu: list | None = None) -> float:
    """Median wall time of ``run()``; its median process CPU time appended to ``cpu``."""
    times, used = [], []
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        run()
        times.append(time.perf_counter() - start)
        used.append(time.process_time() - start_cpu)
    if cpu is not None:
        cpu.append(statistics.median(used))
    return statistics.median(times)


def _cold_start_seconds() -> float:
    """Import, encode and decode of a 64 x 64 map in a new process whose numba cache is empty:
    every kernel compiled (the cost of the very first run after installing)."""
    code = (
        "import time; t = time.perf_counter(); import bandelets; "
        "from bandelets.samples import crease_normal_map; "
        "bandelets.decode(bandelets.encode(crease_normal_map(64), threshold=0.05, kind='normal-map')); "
        "print(time.perf_counter() - t)"
    )
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        command = [sys.executable, "-c", code]
        out = subprocess.run(command, capture_output=True, text=True, env=env, check=True)
    return float(out.stdout.split()[-1])


def _peak_memory_mib(size: int) -> float:
    """Peak resident memory of a process during one bandelet encode (Linux: VmHWM, reset
    after the map is generated so that only the encode counts; imports included)."""
    code = (
        "import bandelets; from bandelets.samples import crease_normal_map; "
        f"n = crease_normal_map({size}, supersampling=1); "
        "open('/proc/self/clear_refs', 'w').write('5'); "
        "bandelets.encode(n, threshold=0.05, kind='normal-map'); "
        "print([l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1])"
    )
    # Twice: the first run may compile numba's kernels (LLVM's memory would count), the
    # second loads them from numba's cache as every later run does.
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1]) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="256,512,1024,2048")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--memory-size", type=int, default=2048)
    args = parser.parse_args()
    print(f"cold start (import, compile every kernel, encode + decode 64^2): {_cold_start_seconds():.2f} s")
    start = time.perf_counter()
    bandelets.decode(bandelets.encode(crease_normal_map(64), threshold=0.05, kind="normal-map"))
    print(f"first call (numba cache load or compile): {time.perf_counter() - start:.2f} s")
    print(
        f"{'size':>5} {'bdl 1bpp':>9} {'bdl T':>7} {'bdl dec':>8} {'j2k enc':>8} {'j2k dec':>8} "
        f"{'avif enc':>9} {'avif dec':>8} {'us/px 1bpp':>10}"
    )
    per_pixel = {}
    for size in (int(s) for s in args.sizes.split(",")):
        normals = crease_normal_map(size, supersampling=1 if size > 1024 else 4)
        data = bandelets.encode(normals, threshold=0.05, kind="normal-map")
        cpu: list[float] = []
        rated = _median_seconds(
            partial(bandelets.encode, normals, bpp=1, kind="normal-map"), args.repeat, cpu
        )
        fixed = _median_seconds(
            partial(bandelets.encode, normals, threshold=0.05, kind="normal-map"), args.repeat, cpu
        )
        decode = _median_seconds(partial(bandelets.decode, data), args.repeat, cpu)
        u16 = np.round((normals + 1) / 2 * 65535).astype(np.uint16)
        u12 = np.round((normals + 1) / 2 * 4095).astype(np.uint16)
        j2k_encode = partial(
            imagecodecs.jpeg2k_encode, u16, level=50, reversible=False, mct=False, codecformat="j2k"
        )
        avif_encode = partial(
            imagecodecs.avif_encode, u12, level=80, speed=6, bitspersample=12, pixelformat="444"
        )
        times = [
            _median_seconds(j2k_encode, args.repeat),
            _median_seconds(partial(imagecodecs.jpeg2k_decode, j2k_encode()), args.repeat),
            _median_seconds(avif_encode, args.repeat),
            _median_seconds(partial(imagecodecs.avif_decode, avif_encode()), args.repeat),
        ]
        per_pixel[size] = rated / size**2 * 1e6
        print(
            f"{size:>5} {rated:>9.3f} {fixed:>7.3f} {decode:>8.3f} "
            + " ".join(f"{t:>8.3f}" for t in times)
            + f" {per_pixel[size]:>10.3f}"
        )
        print(
            f"      bandelets CPU time (all threads): 1 bpp {cpu[0]:.3f} s, T {cpu[1]:.3f} s, "
            f"decode {cpu[2]:.3f} s"
        )
        print(
            f"      ratios to bandelets at 1 bpp: j2k encode x{rated / times[0]:.1f}, "
            f"avif encode x{rated / times[2]:.1f}; decode: j2k x{decode / times[1]:.1f}, "
            f"avif x{decode / times[3]:.1f}"
        )
    if 512 in per_pixel:
        for size, value in per_pixel.items():
            print(f"time per pixel at {size}: {value / per_pixel[512]:.2f} x the 512 one")
    print(f"peak memory of a {args.memory_size}^2 x 3 encode: {_peak_memory_mib(args.memory_size):.0f} MiB")


if __name__ == "__main__":
    main()
