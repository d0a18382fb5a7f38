"""Hausdorff PSNR of geometry-image coding, bandelets against wavelets, on the shared meshes.

For each mesh of ``../shared/data/meshes`` named on the command line: the spherical
parameterization and the N x N geometry image (time and area distortion), the PSNR of the
geometry-image mesh against the original (remeshing alone), then for each transform and
target bits per original vertex a real .bdl file (bytes -> bits per vertex), its decoded
mesh and its Hausdorff PSNR against the geometry-image mesh (compression alone) and against
the original, and the BD-PSNR of bandelets over wavelets.

    python benchmarks/rd_meshes.py [fandisk.off bunny.off ...] [--size 256] [--bpv 2,4,8,16]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from bandelets.metrics import bd_psnr
from bandelets.surfaces import codec, metrics
from bandelets.surfaces.geometry_image import mesh_from_image

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", nargs="*", default=["fandisk.off", "bunny.off"])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--bpv", default="2,4,8,16")
    args = parser.parse_args()
    if not MESHES.is_dir():
        sys.exit(f"{MESHES} is absent: this benchmark needs the shared test meshes")
    for name in args.meshes:
        mesh = codec.load_mesh(MESHES / name)
        start = time.perf_counter()
        image = codec.make_geometry_image(mesh, args.size)
        seconds = time.perf_counter() - start
        remeshed = mesh_from_image(image.positions)
        distortion = {k: round(float(v), 4) for k, v in image.distortion.items()}
        print(
            f"{name}: {len(mesh.vertices)} vertices; parameterization and sampling {seconds:.1f} s; "
            f"distortion {distortion}"
        )
        print(f"  geometry-image mesh vs original: {metrics.hausdorff_psnr(mesh, remeshed):.2f} dB")
        curves = {}
        for transform in ("bandelet", "wavelet"):
            for bpv in (float(b) for b in args.bpv.split(",")):
                data = codec.encode_mesh(
                    mesh, image=image.positions, bits_per_vertex=bpv, transform=transform
                )
                decoded = codec.decode_mesh(data)
                real = 8 * len(data) / len(mesh.vertices)
                alone = metrics.hausdorff_psnr(remeshed, decoded)
                total = metrics.hausdorff_psnr(mesh, decoded)
                curves.setdefault(transform, []).append((real, alone))
                print(
                    f"  {transform:8s} target {bpv:5g} b/v: {len(data):7d} bytes = {real:6.2f} b/v, "
                    f"PSNR vs geometry image {alone:6.2f} dB, vs original {total:6.2f} dB"
                )
        b, w = np.array(curves["bandelet"]), np.array(curves["wavelet"])
        if len(b) >= 4:
            gain = bd_psnr(b[:, 0], b[:, 1], w[:, 0], w[:, 1])
            print(f"  BD-PSNR of bandelets over wavelets (vs geometry image): {gain:+.2f} dB")


if __name__ == "__main__":
    main()
