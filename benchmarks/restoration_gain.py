"""What the decoder-side restoration adds, file by file.

For each surface and target rate, encode once with ``restore=False`` and once with the
default (the encoder picks the number of restoration iterations), check that the two files
have the same size (only one header byte differs), decode both and print the PSNRs, the
iterations chosen and the decode times; then the BD-PSNR of the restored curve over the plain
one. Surfaces: the generated crease and bumps normal maps (bandelets, CDF 9/7) and, when
``../shared/data/meshes`` is there, the normal map of fandisk's 256 x 256 geometry image.

    python benchmarks/restoration_gain.py [--size 256] [--rates 0.25,0.5,1,2] [--meshes DIR]
        [--edge E] [--step S] [--second-order W] [--second-edge E2] [--project-every P]

``--edge``, ``--step``, ``--second-order``, ``--second-edge`` and ``--project-every`` replace
:data:`bandelets.restore.restoration.EDGE`, ``STEP``, ``SECOND_ORDER``, ``SECOND_EDGE`` and
``PROJECT_EVERY`` for this run
(encoder and decoder alike), to measure other choices of the decoder's constants; files made
that way are not .bdl files any other build decodes the same. ``--second-order 0 --edge 0.5``
is the log total variation of format version 4, ``--second-order 0 --edge 1e9`` the plain total
variation of version 3.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import bandelets
from bandelets.format.header import unpack
from bandelets.metrics import bd_psnr, bits_per_pixel, psnr
from bandelets.restore import restoration
from bandelets.samples import bump_normal_map, crease_normal_map


def surfaces(size: int, meshes: Path):
    yield "crease", crease_normal_map(size)
    yield "bumps", bump_normal_map(size)
    fandisk = meshes / "fandisk.off"
    if not fandisk.exists():
        print(f"(skipping fandisk: {fandisk} not found)")
        return
    from bandelets.surfaces.codec import load_mesh, make_geometry_image

    yield "fandisk normals", make_geometry_image(load_mesh(fandisk), size).normals


def _decoded(data: bytes, normals):
    start = time.perf_counter()
    decoded = bandelets.decode(data)
    return psnr(normals, decoded, "normal-map"), time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--rates", default="0.25,0.5,1,2")
    parser.add_argument("--meshes", type=Path, default=Path(__file__).parents[2] / "shared/data/meshes")
    parser.add_argument("--edge", type=float, default=restoration.EDGE, help="EDGE, in units of T")
    parser.add_argument("--step", type=float, default=restoration.STEP, help="STEP, in units of T")
    parser.add_argument("--second-order", type=float, default=restoration.SECOND_ORDER, help="SECOND_ORDER")
    parser.add_argument(
        "--second-edge", type=float, default=restoration.SECOND_EDGE, help="SECOND_EDGE, in units of T"
    )
    parser.add_argument(
        "--project-every", type=int, default=restoration.PROJECT_EVERY, help="PROJECT_EVERY, iterations"
    )
    args = parser.parse_args()
    restoration.EDGE, restoration.STEP, restoration.PROJECT_EVERY = args.edge, args.step, args.project_every
    restoration.SECOND_ORDER, restoration.SECOND_EDGE = args.second_order, args.second_edge
    print(
        f"EDGE {args.edge:g} T, STEP {args.step:g} T, "
        f"SECOND_ORDER {args.second_order:g}, SECOND_EDGE {args.second_edge:g} T, "
        f"PROJECT_EVERY {args.project_every}"
    )
    rates = [float(r) for r in args.rates.split(",")]
    columns = f"{'target':>6} {'bytes':>6} {'plain':>7} {'restored':>8} {'gain':>6} {'iter':>4}  decode"
    print(f"{'surface':<16} {columns}")
    for name, normals in surfaces(args.size, args.meshes):
        curves = {"plain": ([], []), "restored": ([], [])}
        for rate in rates:
            plain = bandelets.encode(normals, bpp=rate, kind="normal-map", restore=False)
            restored = bandelets.encode(normals, bpp=rate, kind="normal-map")
            assert len(plain) == len(restored), "the restoration must not change the size"
            (p0, t0), (p1, t1) = _decoded(plain, normals), _decoded(restored, normals)
            bpp = bits_per_pixel(len(restored), normals.shape)
            for key, value in (("plain", p0), ("restored", p1)):
                curves[key][0].append(bpp)
                curves[key][1].append(value)
            iterations = unpack(restored)[0].restoration
            print(
                f"{name:<16} {rate:>6g} {len(restored):>6} {p0:>7.2f} {p1:>8.2f} {p1 - p0:>+6.2f} "
                f"{iterations:>4}  {t0:.2f} -> {t1:.2f} s"
            )
        gain = bd_psnr(*curves["restored"], *curves["plain"])
        print(f"{name}: BD-PSNR of the restoration {gain:+.2f} dB\n")


if __name__ == "__main__":
    main()
