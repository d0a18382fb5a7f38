"""The decoder's decimation, fast-simplification against MeshLab's quadric edge collapse.

For each closed shared mesh (``../shared/data/meshes``) and rate in bits per vertex: the file
``mesh-encode`` writes, its geometry image decoded and coarsened as ``mesh-decode`` does
(:func:`bandelets.surfaces.codec.decode_mesh`), then decimated to the mesh's vertex count by
MeshLab alone (:func:`bandelets.surfaces.geometry_image.decimate_meshlab`, main's decoder before
issue 38) and by :func:`bandelets.surfaces.geometry_image.decimate` (fast-simplification from 512 x
512 grids up; ``--fast-from 0``: on every grid); CPU seconds of each, and the Hausdorff PSNR of
each against the original (200,000 samples each way).

    PYTHONPATH=src python benchmarks/mesh_decimation.py [fandisk.off bunny.off ...] [--bpv 0.5,1,2,4,8]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bandelets.codec.decoder import decode_parsed
from bandelets.format.header import unpack
from bandelets.surfaces import codec, geometry_image, metrics

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", nargs="*", default=["fandisk.off", "bunny.off", "arm.obj"])
    parser.add_argument("--bpv", default="0.5,1,2,4,8")
    parser.add_argument("--fast-from", type=int, default=geometry_image.FAST_FROM)
    args = parser.parse_args()
    if not MESHES.is_dir():
        sys.exit(f"{MESHES} is absent: this benchmark needs the shared test meshes")
    geometry_image.FAST_FROM = args.fast_from
    print("| mesh | bpv | side | grid | MeshLab dB | s | now dB | s | difference |")
    print("| --- " * 9 + "|")
    for name in args.meshes:
        mesh = codec.load_mesh(MESHES / name)
        spherical = codec.map_to_sphere(mesh)
        n = len(mesh.vertices)
        for bpv in (float(b) for b in args.bpv.split(",")):
            data = codec.encode_mesh(mesh, spherical=spherical, bits_per_vertex=bpv)
            header, streams = unpack(data)
            image = geometry_image.coarsen(
                decode_parsed(header, streams), codec.OVERSAMPLING * n, codec.DECIMATED_PIXELS
            )
            grid = geometry_image.mesh_from_image(image)
            row = []
            for decimate in (geometry_image.decimate_meshlab, geometry_image.decimate):
                start = time.process_time()
                decimated = decimate(grid, n)
                row += [metrics.hausdorff_psnr(mesh, decimated), time.process_time() - start]
            print(
                f"| {name} | {8 * len(data) / n:.2f} | {header.width} | {image.shape[0]} | {row[0]:.2f} | "
                f"{row[1]:.2f} | {row[2]:.2f} | {row[3]:.2f} | {row[2] - row[0]:+.2f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
