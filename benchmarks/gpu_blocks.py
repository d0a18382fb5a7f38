"""The angle BC5, BC7 and RGBA8 add to the shared normal maps, and the time of a KTX2 with mips.

    python benchmarks/gpu_blocks.py                  # every PNG of ../shared/data/normal-maps
    python benchmarks/gpu_blocks.py --etcpak-bc5     # also etcpak's BC5, the encoder not chosen

(from the repository root; about half a minute.) Each map is read as 8-bit RGB, made unit vectors
(z rebuilt from x and y for the maps that store only those),
and written by :func:`bandelets.io.gpu.export` to a KTX2 file with its full mip chain; the table
gives the file's bytes, its bits per texel of level 0 (8 x bytes / texels, the mips included),
the mean and 99th-percentile angle the format adds to level 0 (decoded by texture2ddecoder), and
the seconds the export took (mips, blocks, decoding for the check, writing).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

from bandelets.io import gpu

MAPS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "normal-maps"
# Maps that store x and y only (the acacia door's blue is its ambient occlusion), as rd_normal_maps.py.
XY_MAPS = ("acacia_door_bottom_n.png",)


def _unit(path: Path) -> np.ndarray:
    with Image.open(path) as image:
        rgb = np.asarray(image.convert("RGB"), dtype=np.float64) / 127.5 - 1.0
    return gpu.to_unit(rgb[..., :2] if path.name in XY_MAPS else rgb)


def _etcpak_bc5(n: np.ndarray) -> gpu.AngularError:
    import etcpak
    import texture2ddecoder

    h, w = n.shape[:2]
    rgba = np.full((h, w, 4), 255, np.uint8)
    rgba[..., :3] = np.round((n + 1) * 127.5)
    rgba = np.pad(rgba, ((0, -h % 4), (0, -w % 4), (0, 0)), mode="edge")
    ph, pw = rgba.shape[:2]
    blocks = etcpak.compress_bc5(rgba.tobytes(), pw, ph)
    bgra = np.frombuffer(texture2ddecoder.decode_bc5(blocks, pw, ph), np.uint8).reshape(ph, pw, 4)
    return gpu.angular_error_added(n, bgra[:h, :w, [2, 1]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", type=Path, default=MAPS, help="folder of PNG normal maps")
    parser.add_argument("--etcpak-bc5", action="store_true", help="also etcpak's BC5 (level 0)")
    args = parser.parse_args()
    paths = sorted(args.maps.glob("*.png"))
    if not paths:
        raise SystemExit(f"no PNG normal maps in {args.maps}")
    print(f"{'map':34} {'size':>11} {'format':8} {'bytes':>9} {'bpp':>5} {'mean':>6} {'p99':>6} {'s':>5}")
    with tempfile.TemporaryDirectory() as folder:
        for path in paths:
            n = _unit(path)
            h, w = n.shape[:2]
            for fmt in gpu.FORMATS:
                start = time.perf_counter()
                result = gpu.export(Path(folder) / "out.ktx2", n, fmt)
                seconds = time.perf_counter() - start
                bpp = 8 * result.file_bytes / (w * h)
                print(
                    f"{path.stem:34} {w:>5} x {h:<5} {fmt:8} {result.file_bytes:>9} {bpp:>5.2f} "
                    f"{result.error.mean:>6.3f} {result.error.p99:>6.3f} {seconds:>5.2f}"
                )
            if args.etcpak_bc5:
                error = _etcpak_bc5(n)
                blank = ""
                print(f"{path.stem:34} {w:>5} x {h:<5} {'bc5-etc':8} {blank:>15} ", end="")
                print(f"{error.mean:>6.3f} {error.p99:>6.3f}")


if __name__ == "__main__":
    main()
