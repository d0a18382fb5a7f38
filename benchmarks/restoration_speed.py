"""What the decoder-side restoration costs, beside OpenJPEG in the same run.

The generated crease normal map of side ``--size`` encoded at 1 bpp with the defaults; then, over
``--repeat`` runs: the process CPU time of the restoration alone (:func:`bandelets.codec.decoder.restorations`
up to the count the file asks for, from the decoded bins: all threads), the wall and CPU time of
:func:`bandelets.decode`, of the encode, and the wall time of OpenJPEG's encode of the same map
(16-bit, the figure to divide by on a shared machine). Prints medians, one line. Run it with
another build on the path (``PYTHONPATH=OTHER/src``) to compare builds in one session.

    python benchmarks/restoration_speed.py [--size 512] [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import time
from itertools import islice

import imagecodecs
import numpy as np

import bandelets
from bandelets.codec import decoder
from bandelets.format import header as bitstream
from bandelets.samples import crease_normal_map


def _timed(function, *args, **kwargs):
    wall, cpu = time.perf_counter(), time.process_time()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - wall, time.process_time() - cpu


def _restored(header, trees, bins, lifting):
    """The channels after the restoration the file asks for (what decode runs after the bins)."""
    return next(islice(decoder.restorations(header, trees, bins, lifting), header.restoration, None))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=512, help="side of the crease map (default 512)")
    parser.add_argument("--repeat", type=int, default=5, help="runs to take the medians of (default 5)")
    args = parser.parse_args()
    x = crease_normal_map(args.size)
    samples = np.round((x + 1) / 2 * 65535).astype(np.uint16)
    bandelets.decode(bandelets.encode(x, bpp=1.0, kind="normal-map"))  # compiled, caches warm
    runs = []
    for _ in range(args.repeat):
        data, encode_wall, encode_cpu = _timed(bandelets.encode, x, bpp=1.0, kind="normal-map")
        header, streams = bitstream.unpack(data)
        trees, bins, lifting = decoder.decoded_bins(header, streams)
        _, _, restoration_cpu = _timed(_restored, header, trees, bins, lifting)
        _, decode_wall, decode_cpu = _timed(bandelets.decode, data)
        _, openjpeg, _ = _timed(
            imagecodecs.jpeg2k_encode, samples, level=45, codecformat="j2k", reversible=False, mct=False
        )
        runs.append((restoration_cpu, decode_wall, decode_cpu, encode_wall, encode_cpu, openjpeg))
    r, dw, dc, ew, ec, j = (statistics.median(column) for column in zip(*runs, strict=True))
    print(
        f"crease {args.size}^2 at 1 bpp, format {bitstream.FORMAT_VERSION}, {header.restoration} iterations: "
        f"restoration CPU {r:.3f} s; decode {dw:.3f} s wall, {dc:.3f} s CPU; encode {ew:.2f} s wall, "
        f"{ec:.2f} s CPU; OpenJPEG encode {j:.3f} s; decode / OpenJPEG {dw / j:.1f}"
    )


if __name__ == "__main__":
    main()
