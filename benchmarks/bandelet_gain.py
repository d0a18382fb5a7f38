"""The bandelet gain on the generated crease normal map, and encode / decode times.

For each variant (the wavelet baseline, bandelets with Haar as in the paper, bandelets with
the default Alpert transform), encode at each target rate with rate control, write nothing
but measure the real file size, decode, and print bpp and PSNR, then the BD-PSNR of each
bandelet variant over the wavelet baseline. Then the median encode time at a fixed
threshold and the median decode time for the default codec.

    python benchmarks/bandelet_gain.py [--size 512] [--rates 0.25,0.5,1,2] [--repeat 3] [--wavelet auto]
"""

from __future__ import annotations

import argparse
import statistics
import time

import bandelets
from bandelets.metrics import bd_psnr, bits_per_pixel, psnr
from bandelets.samples import crease_normal_map

VARIANTS = {
    "wavelet": {"transform": "wavelet"},
    "bandelet-haar": {"transform_1d": "haar"},
    "bandelet-alpert2": {"transform_1d": "alpert2"},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--rates", default="0.25,0.5,1,2")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--wavelet", default="cdf97", help="cdf97 (default), haar, ... or auto")
    args = parser.parse_args()
    normals = crease_normal_map(args.size)
    rates = [float(r) for r in args.rates.split(",")]
    curves = {}
    print(f"crease normal map {args.size} x {args.size}")
    print(f"{'variant':<17} {'target':>6} {'bytes':>7} {'bpp':>7} {'PSNR':>7}")
    for name, options in VARIANTS.items():
        points = []
        for rate in rates:
            data = bandelets.encode(normals, bpp=rate, kind="normal-map", wavelet=args.wavelet, **options)
            quality = psnr(normals, bandelets.decode(data), "normal-map")
            points.append((bits_per_pixel(len(data), normals.shape), quality))
            print(f"{name:<17} {rate:>6g} {len(data):>7d} {points[-1][0]:>7.4f} {quality:>7.2f}")
        curves[name] = ([p[0] for p in points], [p[1] for p in points])
    for name in ("bandelet-haar", "bandelet-alpert2"):
        print(f"BD-PSNR {name} over wavelet: {bd_psnr(*curves[name], *curves['wavelet']):+.3f} dB")
    data = bandelets.encode(normals, threshold=0.05, kind="normal-map")
    encode_s, decode_s = [], []
    for _ in range(args.repeat):
        start = time.perf_counter()
        data = bandelets.encode(normals, threshold=0.05, kind="normal-map")
        encode_s.append(time.perf_counter() - start)
        start = time.perf_counter()
        bandelets.decode(data)
        decode_s.append(time.perf_counter() - start)
    print(
        f"encode at T = 0.05 ({len(data)} bytes): median {statistics.median(encode_s):.2f} s; "
        f"decode: median {statistics.median(decode_s):.2f} s"
    )


if __name__ == "__main__":
    main()
