"""The longest decode the default limits allow, beside OpenJPEG on the same image.

The restoration is what can make a small file slow to decode (a few hundred bytes can describe
an image of millions of samples restored for 100 iterations): ``max_work``
(:func:`bandelets.format.limits.check_work`) bounds it. For each size, a near-empty image is coded
without restoration, then its header asks for as many iterations as the default ``max_work``
allows; the decode is timed (wall and process CPU) beside OpenJPEG's decode of a 16-bit image of
the same size, with the time per iteration and per sample-iteration.

    python benchmarks/worst_decode.py [--sizes 1024,2048]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import imagecodecs
import numpy as np

import bandelets
from bandelets.format.fields import MAX_RESTORATION, MAX_WORK
from bandelets.format.header import pack, unpack
from bandelets.format.limits import restoration_work


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="1024,2048")
    sizes = [int(s) for s in parser.parse_args().sizes.split(",")]
    rng = np.random.default_rng(0)
    print("size    file B  iterations  work        decode s  cpu s   ms/iteration  ns/sample-it  OpenJPEG s")
    for size in sizes:
        x = np.zeros((size, size))
        x[size // 2, size // 3] = 1.0  # near-empty, as in issue 18
        header, streams = unpack(bandelets.encode(x, threshold=0.1, restore=False))
        per_iteration = restoration_work(replace(header, restoration=1))
        iterations = min(MAX_RESTORATION, MAX_WORK // per_iteration)
        data = pack(replace(header, restoration=iterations), streams)
        bandelets.decode(pack(header, streams))  # compile and cache outside the clock
        start, cpu = time.perf_counter(), time.process_time()
        bandelets.decode(data)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
        start = time.perf_counter()
        bandelets.decode(pack(header, streams))
        plain = time.perf_counter() - start
        j2k = imagecodecs.jpeg2k_encode(rng.integers(0, 65536, (size, size), dtype=np.uint16))
        start = time.perf_counter()
        imagecodecs.jpeg2k_decode(j2k)
        openjpeg = time.perf_counter() - start
        work = restoration_work(replace(header, restoration=iterations))
        print(
            f"{size:<7d} {len(data):<7d} {iterations:<11d} {work:<11.3g} {seconds:<9.1f} {cpu:<7.1f} "
            f"{1e3 * (seconds - plain) / iterations:<13.0f} {1e9 * (seconds - plain) / work:<13.0f} "
            f"{openjpeg:.3f} (x{seconds / openjpeg:.0f})"
        )


if __name__ == "__main__":
    main()
