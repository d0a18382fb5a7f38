"""The decoder-side restoration alone, on fixed files: what a change of the restoration gives.

    python benchmarks/restoration_variants.py [--maps crease256,crease512,acacia,lava,fandisk,bunny]
        [--rates 0.25,0.5,1,2] [--cache out/restoration-variants] [--no-lifting] [--set NAME=VALUE ...]

Each map is encoded once per rate with the defaults but ``restore=False`` (the files are cached
under ``--cache``: a restored file has the same bytes but for the header's iteration count). The
restoration of this build is then run on the decoded bins as the encoder runs it: every iteration
measured against the source (as the encoder measures, at the source's depth), the count the
encoder would write (the fewest iterations keeping :data:`bandelets.codec.encoder.RESTORATION_SHARE` of
the best gain, up to :data:`bandelets.codec.encoder._RESTORATION_PATIENCE` past the best). Printed per
point: the plain PSNR, the restored PSNR at that count, the count and the restoration's time
(without the loop filter that follows it, :mod:`bandelets.restore.loopfilter`);
per map the mean gain over plain dequantization (the files are the same, so this is the BD-PSNR of
the restoration at equal rates). Compare two builds (or two settings) by the restored columns.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import imagecodecs
import numpy as np

import bandelets
from bandelets import metrics
from bandelets.codec import encoder
from bandelets.codec.decoder import decoded_bins, restorations
from bandelets.format.fields import FORMAT_VERSION
from bandelets.format.header import unpack
from bandelets.restore import restoration
from bandelets.samples import crease_normal_map

HERE = Path(__file__).resolve().parent
SHARED = HERE.parents[1] / "shared/data"


def _png(name: str) -> tuple[np.ndarray, int]:
    pixels = imagecodecs.png_decode((SHARED / "normal-maps" / name).read_bytes())[..., :3]
    if name.startswith("acacia"):  # X and Y only (benchmarks/rd_normal_maps.py)
        xy = pixels[..., :2] / 255.0 * 2.0 - 1.0
        z = np.sqrt(np.clip(1.0 - np.sum(xy * xy, axis=-1), 0.0, 1.0))
        pixels = pixels.copy()
        pixels[..., 2] = np.rint((z + 1.0) / 2.0 * 255.0).astype(np.uint8)
    return pixels.astype(np.float64) / 255.0 * 2.0 - 1.0, 8


def _mesh(name: str) -> tuple[np.ndarray, int]:
    from bandelets.surfaces.codec import load_mesh, make_geometry_image

    return make_geometry_image(load_mesh(SHARED / "meshes" / name), 256).normals, 0


MAPS = {
    "crease256": lambda: (crease_normal_map(256), 0),
    "crease512": lambda: (crease_normal_map(512), 0),
    "acacia": lambda: _png("acacia_door_bottom_n.png"),
    "lava": lambda: _png("lava_flow_n.png"),
    "fandisk": lambda: _mesh("fandisk.off"),
    "bunny": lambda: _mesh("bunny.off"),
}


def restored(data: bytes, vectors, depth: int, most: int = 100) -> tuple[float, float, int, float]:
    """Plain PSNR, restored PSNR at the count the encoder would write, that count, seconds."""
    header, streams = unpack(data)
    equidistant = header.channels == 2 and header.layout == "xyz"
    measure = metrics.psnr_of_channels(vectors, "normal-map", depth, equidistant)
    trees, bins, lifting = decoded_bins(header, streams)
    scores = []
    start = time.perf_counter()
    for n, channels in enumerate(restorations(header, trees, bins, lifting)):
        scores.append(measure(channels))
        if n == most or n - int(np.argmax(scores)) >= encoder._RESTORATION_PATIENCE:
            break
    seconds = time.perf_counter() - start
    best = int(np.argmax(scores))
    if best > 0:
        share = encoder.RESTORATION_SHARE * (scores[best] - scores[0])
        best = next(n for n, s in enumerate(scores) if s - scores[0] >= share)
    return scores[0], scores[best], best, seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", default=",".join(MAPS))
    parser.add_argument("--rates", default="0.25,0.5,1,2")
    parser.add_argument("--cache", type=Path, default=Path("out/restoration-variants"))
    parser.add_argument("--no-lifting", action="store_true", help="files coded with --no-lifting")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a constant of bandelets.restore.restoration",
    )
    args = parser.parse_args()
    for assignment in args.set:
        key, value = assignment.split("=")
        setattr(restoration, key, type(getattr(restoration, key))(value))
    rates = [float(r) for r in args.rates.split(",")]
    args.cache.mkdir(parents=True, exist_ok=True)
    total = []
    for name in args.maps.split(","):
        vectors, depth = MAPS[name]()
        gains, finals = [], []
        for rate in rates:
            path = args.cache / f"{name}-{rate:g}{'-plain' if args.no_lifting else ''}.bdl"
            if not path.exists() or path.read_bytes()[4] != FORMAT_VERSION:  # none, or of another build
                options = {"lifting": False} if args.no_lifting else {}
                path.write_bytes(
                    bandelets.encode(
                        vectors, bpp=rate, kind="normal-map", depth=depth, restore=False, **options
                    )
                )
            data = path.read_bytes()
            lifted = unpack(data)[0].lifting
            p0, p1, n, seconds = restored(data, vectors, depth)
            gains.append(p1 - p0)
            finals.append(p1)
            print(
                f"{name:<10} {rate:>5g} bpp lifted {lifted}: {p0:6.2f} -> {p1:6.2f} ({p1 - p0:+.2f}) "
                f"{n:3d} it. {seconds:.2f} s",
                flush=True,
            )
        total.append(np.mean(gains))
        print(
            f"{name}: mean restored {np.mean(finals):.3f} dB, mean gain {np.mean(gains):+.3f} dB", flush=True
        )
    print(f"mean gain over the maps {np.mean(total):+.3f} dB")


if __name__ == "__main__":
    main()
