"""Time and peak memory of one encode and one decode of a large generated normal map, beside
OpenJPEG and AVIF in the same process (the machine may be shared: quote the ratios).

One process per size (each measurement too long to repeat): the crease normal map (point
sampled), encoded at 1 bpp (rate control and the restoration search included, unless
``--no-restore``), decoded (restoration as the file asks) and decoded without restoration; wall
and process CPU time (all threads) of each, and the peak resident memory of the encode and of
the decode (Linux: VmHWM, reset once the map, or the file, is made; imports and the map
itself included; the decode's in a new process), and the PSNR of the decoded map. ``--uint8``
holds the map as 8-bit samples, as read from a PNG (its float64 array alone is 1.5 GiB at 8192
x 8192). Maps are coded as the library's default does: in one piece when that fits the memory
limit, in tiles of 512 above (:func:`bandelets.format.limits.tile_side`); ``--tile N`` for tiles at any
size.

    python benchmarks/large_maps.py 4096 [--no-restore] [--uint8] [--tile 512]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time

import imagecodecs
import numpy as np

import bandelets
from bandelets.format.container import header_of
from bandelets.metrics import psnr
from bandelets.samples import crease_normal_map


def _peak_mib() -> float:
    return int(next(line for line in open("/proc/self/status") if line.startswith("VmHWM")).split()[1]) / 1024


def _reset_peak() -> None:
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def _decode_peak_mib(data: bytes) -> float:
    """Peak RSS of a new process decoding ``data`` (VmHWM reset once the file is read): the
    encoder's freed heap would count in this one."""
    with tempfile.NamedTemporaryFile(suffix=".bdl") as f:
        f.write(data)
        f.flush()
        code = (
            "import bandelets; "
            f"data = open({f.name!r}, 'rb').read(); "
            "open('/proc/self/clear_refs', 'w').write('5'); bandelets.decode(data); "
            "print(next(l for l in open('/proc/self/status') if l.startswith('VmHWM')).split()[1])"
        )
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1]) / 1024


def _timed(run):
    start, cpu = time.perf_counter(), time.process_time()
    out = run()
    return out, time.perf_counter() - start, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("size", type=int)
    parser.add_argument("--no-restore", action="store_true")
    parser.add_argument("--uint8", action="store_true")
    parser.add_argument("--tile", type=int, default=0, help="tile side (default 0: the library's choice)")
    args = parser.parse_args()
    bandelets.decode(bandelets.encode(crease_normal_map(64), threshold=0.05, kind="normal-map"))
    normals = crease_normal_map(args.size, supersampling=1)
    samples = np.round((normals + 1) * 127.5).astype(np.uint8)
    source = samples if args.uint8 else normals
    if args.uint8:
        del normals
    u16 = np.round((source.astype(np.float64) / 255 if args.uint8 else (source + 1) / 2) * 65535).astype(
        np.uint16
    )
    j2k, j2k_s, _ = _timed(
        lambda: imagecodecs.jpeg2k_encode(u16, level=50, reversible=False, mct=False, codecformat="j2k")
    )
    _, j2k_dec_s, _ = _timed(lambda: imagecodecs.jpeg2k_decode(j2k))
    u12 = (u16 >> 4).astype(np.uint16)
    avif, avif_s, _ = _timed(
        lambda: imagecodecs.avif_encode(u12, level=80, speed=6, bitspersample=12, pixelformat="444")
    )
    _, avif_dec_s, _ = _timed(lambda: imagecodecs.avif_decode(avif))
    u16 = u12 = None  # freed before the measured calls
    _reset_peak()
    data, enc_s, enc_cpu = _timed(
        lambda: bandelets.encode(
            source, bpp=1, kind="normal-map", restore=not args.no_restore, tile=args.tile
        )
    )
    enc_peak = _peak_mib()
    decoded, dec_s, dec_cpu = _timed(lambda: bandelets.decode(data))
    # Not of --uint8 maps: their float64 copy is what that option avoids.
    quality = float("nan") if args.uint8 else psnr(source, decoded, "normal-map")
    del decoded
    dec_peak = _decode_peak_mib(data)
    _, plain_s, plain_cpu = _timed(lambda: bandelets.decode(data, restore=False))
    header = header_of(data)
    per_pixel = 1e6 / args.size**2
    bpp = 8 * len(data) / args.size**2
    lines = [
        f"{args.size} x {args.size} x 3 {'uint8' if args.uint8 else 'float64'}, 1 bpp"
        f"{', no restoration' if args.no_restore else ''}: {len(data)} bytes ({bpp:.3f} bpp), "
        f"restoration up to {header.restoration} iterations a tile, PSNR {quality:.2f} dB",
        f"  encode {enc_s:.1f} s (CPU {enc_cpu:.1f} s, {enc_cpu * per_pixel:.2f} us/px, "
        f"peak RSS {enc_peak:.0f} MiB)",
        f"  decode {dec_s:.1f} s (CPU {dec_cpu:.1f} s, {dec_cpu * per_pixel:.2f} us/px, "
        f"peak RSS {dec_peak:.0f} MiB), without restoration {plain_s:.1f} s (CPU {plain_cpu:.1f} s)",
        f"  OpenJPEG 16-bit: encode {j2k_s:.2f} s, decode {j2k_dec_s:.2f} s; "
        f"AVIF 12-bit speed 6: encode {avif_s:.2f} s, decode {avif_dec_s:.2f} s",
        f"  ratios: encode x{enc_s / j2k_s:.0f} OpenJPEG, x{enc_s / avif_s:.0f} AVIF; "
        f"decode x{dec_s / j2k_dec_s:.0f} OpenJPEG, x{dec_s / avif_dec_s:.0f} AVIF",
    ]
    print("\n".join(lines), flush=True)


if __name__ == "__main__":
    main()
