"""``bandelets demo``: the bandelet codec against its own wavelet baseline on a generated map.

Writes the generated normal map (16-bit PNG), one .bdl file per codec and rate, and prints
a table of real file sizes and PSNRs measured on the decoded files, then the BD-PSNR of
bandelets over wavelets.
"""

from __future__ import annotations

import time
from pathlib import Path

from tqdm import tqdm

from ..codec.decoder import decode
from ..codec.encoder import encode
from ..io.files import write_array, write_atomic
from ..metrics import bd_psnr, bits_per_pixel, psnr
from ..samples import crease_normal_map

__all__ = ["run_demo"]


def run_demo(size: int, rates: list[float], out: Path, progress: bool = False) -> list[dict]:
    """Compress the generated crease normal map at each rate with both transforms.

    Returns the rows of the printed table (codec, target, bytes, bpp, psnr, seconds).
    """
    out.mkdir(parents=True, exist_ok=True)
    normals = crease_normal_map(size)
    write_array(out / "crease-normals.png", normals, "normal-map", 16)
    rows = []
    runs = [(t, r) for t in ("bandelet", "wavelet") for r in rates]
    for transform, rate in tqdm(runs, desc="demo", disable=not progress):
        start = time.perf_counter()
        data = encode(normals, bpp=rate, kind="normal-map", transform=transform)
        encode_s = time.perf_counter() - start
        path = out / f"{transform}-{rate:g}bpp.bdl"
        write_atomic(path, data)
        start = time.perf_counter()
        decoded = decode(path.read_bytes())
        decode_s = time.perf_counter() - start
        rows.append(
            {
                "codec": transform,
                "target": rate,
                "bytes": len(data),
                "bpp": bits_per_pixel(len(data), normals.shape),
                "psnr": psnr(normals, decoded, "normal-map"),
                "encode_s": encode_s,
                "decode_s": decode_s,
            }
        )
    print(f"crease normal map {size} x {size}, files in {out}/")
    print(f"{'codec':<9} {'target':>7} {'bytes':>8} {'bpp':>7} {'PSNR dB':>8} {'enc s':>6} {'dec s':>6}")
    for r in rows:
        print(
            f"{r['codec']:<9} {r['target']:>7g} {r['bytes']:>8d} {r['bpp']:>7.4f} {r['psnr']:>8.2f} "
            f"{r['encode_s']:>6.2f} {r['decode_s']:>6.2f}"
        )
    if len(rates) >= 4:
        curves = {
            t: ([r["bpp"] for r in rows if r["codec"] == t], [r["psnr"] for r in rows if r["codec"] == t])
            for t in ("bandelet", "wavelet")
        }
        gain = bd_psnr(*curves["bandelet"], *curves["wavelet"])
        print(f"BD-PSNR of bandelets over wavelets: {gain:+.2f} dB")
    return rows
