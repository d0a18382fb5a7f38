"""Where a decode without restoration spends its time, stage by stage, beside OpenJPEG.

The crease normal map of ``--size`` coded at 1 bpp with the defaults (``benchmarks/speed.py``'s
file), then, ``--repeat`` times, a whole ``bandelets.decode(data, restore=False)`` and each of its
stages on its own: parsing the container, entropy decoding (quadtrees, directions and bins:
:func:`bandelets.codec.decoder.decoded_bins`), dequantization and inverse transform (the first step of
:func:`bandelets.codec.decoder.restorations`) and the output (unit normals,
:func:`bandelets.codec.decoder.decoded_image`). Medians of wall and process CPU time (all threads),
with OpenJPEG's decode of the same map (16-bit, as ``speed.py`` codes it) timed in the same run.

    python benchmarks/decode_stages.py [--size 512] [--repeat 15]
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import imagecodecs
import numpy as np

import bandelets
from bandelets.codec.decoder import decoded_bins, decoded_image, restorations
from bandelets.format.header import unpack
from bandelets.samples import crease_normal_map


def _medians(runs: dict, repeat: int) -> dict[str, tuple[float, float]]:
    """Median wall and process CPU seconds of each ``runs[name]()``, the runs taking turns (a
    shared machine's load then weighs on all of them alike)."""
    times = {name: ([], []) for name in runs}
    for _ in range(repeat):
        for name, run in runs.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            run()
            times[name][0].append(time.perf_counter() - start)
            times[name][1].append(time.process_time() - start_cpu)
    return {name: (statistics.median(wall), statistics.median(cpu)) for name, (wall, cpu) in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args()
    normals = crease_normal_map(args.size)
    data = bandelets.encode(normals, bpp=1, kind="normal-map")
    header, streams = unpack(data)
    plain = replace(header, restoration=0)
    trees, quantized, lifting = decoded_bins(header, streams)
    channels = np.array(next(restorations(plain, trees, quantized, lifting)))
    u16 = np.round((normals + 1) / 2 * 65535).astype(np.uint16)
    j2k = imagecodecs.jpeg2k_encode(u16, level=50, reversible=False, mct=False, codecformat="j2k")
    bandelets.decode(data, restore=False)  # kernels loaded
    stages = {
        "decode(restore=False)": lambda: bandelets.decode(data, restore=False),
        "  parse": lambda: unpack(data),
        "  entropy decoding": lambda: decoded_bins(header, streams),
        "  dequantize + inverse transform": lambda: next(restorations(plain, trees, quantized, lifting)),
        "  output (unit normals)": lambda: decoded_image(channels, header),
        "OpenJPEG decode": lambda: imagecodecs.jpeg2k_decode(j2k),
    }
    print(f"{args.size} x {args.size} crease map, {len(data)} bytes; OpenJPEG file {len(j2k)} bytes")
    print(f"{'stage':<34} {'wall ms':>8} {'cpu ms':>8}")
    results = _medians(stages, args.repeat)
    for name, (wall, cpu) in results.items():
        print(f"{name:<34} {wall * 1e3:>8.1f} {cpu * 1e3:>8.1f}")
    whole, j2k_wall = results["decode(restore=False)"][0], results["OpenJPEG decode"][0]
    print(f"decode without restoration / OpenJPEG decode, wall: x{whole / j2k_wall:.1f}")


if __name__ == "__main__":
    main()
