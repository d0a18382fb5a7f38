"""Speed of the directionally lifted transform against the plain CDF 9/7 one, and of the
encoder with and without the directions, on the generated crease normal map.

    python benchmarks/directional_speed.py [--size 512] [--repeat 10] [--threshold 0.01]

Prints the process CPU time (median of ``--repeat``; all threads) of an analysis and of a
synthesis of the map's two channels (x, y) over 6 levels, lifted along the directions
:func:`bandelets.transform.directional.analysis` chooses at ``--threshold`` and plain
(:func:`bandelets.transform.wavelets.wavedec`, :func:`bandelets.transform.wavelets.waverec`), of that
direction
search, of the check that the directions pay (:func:`bandelets.transform.directional.pays`), then the CPU
time of ``bandelets.encode(map, bpp=1, kind="normal-map")`` and of its decode with
``lifting=False`` and by default, with OpenJPEG's encode of the same map in the same run.
"""

from __future__ import annotations

import argparse
import time

import imagecodecs
import numpy as np

import bandelets
from bandelets.samples import crease_normal_map
from bandelets.transform import directional
from bandelets.transform.wavelets import wavedec, waverec

LEVELS = 6


def cpu(function, repeat: int) -> float:
    """Median process CPU time of ``function()``, in seconds, after one warm-up call."""
    function()
    times = []
    for _ in range(repeat):
        start = time.process_time()
        function()
        times.append(time.process_time() - start)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeat", type=int, default=10)
    parser.add_argument("--threshold", type=float, default=0.01)
    args = parser.parse_args()
    x = crease_normal_map(args.size)
    channels = [np.ascontiguousarray(x[..., k]) for k in range(2)]
    t = args.threshold
    lifted, fields = directional.analysis(channels, LEVELS, directional.LEVELS, threshold=t)
    plain = [wavedec(c, "cdf97", LEVELS) for c in channels]
    moved = sum(int(np.count_nonzero(f)) for f in fields), sum(f.size for f in fields)
    ms = {
        "lifted analysis": cpu(
            lambda: directional.analysis(channels, LEVELS, directional.LEVELS, fields), args.repeat
        ),
        "lifted synthesis": cpu(
            lambda: [directional.synthesis(c, LEVELS, directional.LEVELS, fields) for c in lifted],
            args.repeat,
        ),
        "plain analysis": cpu(lambda: [wavedec(c, "cdf97", LEVELS) for c in channels], args.repeat),
        "plain synthesis": cpu(lambda: [waverec(c.copy(), "cdf97", LEVELS) for c in plain], args.repeat),
        "direction search (+ analysis)": cpu(
            lambda: directional.analysis(channels, LEVELS, directional.LEVELS, threshold=t), 3
        ),
        "check that they pay": cpu(
            lambda: directional.pays(channels, lifted, fields, LEVELS, directional.LEVELS, t), 3
        ),
    }
    print(f"{args.size} x {args.size} x 2 channels, T = {t}: {moved[0]} of {moved[1]} blocks lifted off 0")
    for name, seconds in ms.items():
        print(f"  {name}: {1e3 * seconds:.1f} ms CPU")
    ref = np.round((x + 1) / 2 * 65535).astype(np.uint16)
    j2k = cpu(
        lambda: imagecodecs.jpeg2k_encode(ref, level=45, codecformat="j2k", reversible=False, mct=False), 3
    )
    for lifting in (False, None):
        data = bandelets.encode(x, bpp=1.0, kind="normal-map", lifting=lifting)
        encode = cpu(
            lambda lifting=lifting: bandelets.encode(x, bpp=1.0, kind="normal-map", lifting=lifting), 3
        )
        decode = cpu(lambda data=data: bandelets.decode(data), 3)
        print(
            f"  encode at 1 bpp, lifting={lifting}: {encode:.2f} s CPU ({encode / j2k:.0f}x OpenJPEG's), "
            f"decode {decode:.3f} s CPU, {len(data)} bytes"
        )


if __name__ == "__main__":
    main()
