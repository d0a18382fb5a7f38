"""Time of every stage of mesh coding on a large closed genus-0 mesh (target: under a minute).

The mesh is one of ``../shared/data/meshes`` refined by Loop subdivision (default: the bunny,
3,485 vertices, twice: 55,730 vertices). Stages: load, subdivide (not part of the pipeline),
checks, spherical parameterization, sampling of the geometry image, encoding at a rate in
bits per original vertex (side of the geometry image: the one ``mesh-encode`` picks for the
rate, :func:`bandelets.surfaces.codec.auto_size`, unless ``--size``), decoding the file to a mesh
of the original's vertex count as ``mesh-decode`` does by default (the image decoded, rebuilt
and decimated: :func:`bandelets.surfaces.codec.decode_mesh`); then the Hausdorff PSNR of the
decoded mesh against the original (not timed in the total). Wall and CPU seconds (the CPU time
counts every thread, so it may exceed the wall time on two cores; the machine is shared: the wall
time shows its load). The numba kernels are compiled (or loaded from their cache) by a tiny
encode before the clock starts.

    python benchmarks/mesh_pipeline.py [--mesh bunny.off] [--subdivide 2] [--size N] [--bpv 4]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

import bandelets
from bandelets.surfaces import checks, geometry_image, metrics, sphere
from bandelets.surfaces.codec import auto_size, decode_mesh, encode_mesh, load_mesh

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", default="bunny.off")
    parser.add_argument("--subdivide", type=int, default=2, help="Loop subdivision steps (default 2)")
    parser.add_argument("--size", type=int, default=None, help="default: chosen for the rate")
    parser.add_argument("--bpv", type=float, default=4.0, help="bits per original vertex (default 4)")
    args = parser.parse_args()
    if not MESHES.is_dir():
        sys.exit(f"{MESHES} is absent: this benchmark needs the shared test meshes")
    bandelets.encode(np.random.default_rng(0).normal(size=(32, 32, 3)), bpp=2.0, kind="geometry-image")

    times, cpu = {}, {}

    def stage(name, call, *a, **k):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = call(*a, **k)
        times[name] = time.perf_counter() - start
        cpu[name] = time.process_time() - start_cpu
        print(f"{name:28s} {times[name]:7.2f} s  (CPU {cpu[name]:7.2f} s)", flush=True)
        return result

    mesh = stage("load", load_mesh, MESHES / args.mesh)
    subdivision = time.perf_counter()
    mesh = mesh.subdivide_loop(args.subdivide) if args.subdivide else mesh
    print(f"(subdivide x{args.subdivide}: {time.perf_counter() - subdivision:.2f} s, not counted)")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    print(f"{len(vertices)} vertices, {len(faces)} faces")
    stage("checks", checks.check_genus0, vertices, faces)
    if mesh.volume < 0:
        faces = faces[:, ::-1]
    mapped = stage("spherical parameterization", sphere.spherical_parameterization, vertices, faces)
    print(f"  {mapped.levels} levels, {mapped.iterations} relaxation steps, distortion {mapped.distortion}")
    size = args.size or auto_size(args.bpv * len(vertices))
    image, _ = stage(f"sampling {size} x {size}", geometry_image.sample, vertices, faces, mapped.points, size)
    data = stage("encode", encode_mesh, mesh, image=image, bits_per_vertex=args.bpv)
    rebuilt = stage("decode to a mesh", decode_mesh, data)
    print(f"  {len(rebuilt.vertices)} vertices decoded")
    total = sum(times.values())
    print(
        f"{'total':28s} {total:7.2f} s  (CPU {sum(cpu.values()):7.2f} s; "
        f"{8 * len(data) / len(vertices):.2f} bits per vertex; load average {os.getloadavg()[0]:.1f})"
    )
    # The machine is shared and its speed varies: OpenJPEG on a 1024 x 1024 RGB image, timed
    # now, is the yardstick.
    import imagecodecs

    picture = (np.random.default_rng(0).random((1024, 1024, 3)) * 255).astype(np.uint8)
    start = time.perf_counter()
    imagecodecs.jpeg2k_encode(picture, level=0)
    openjpeg = time.perf_counter() - start
    print(
        f"OpenJPEG lossless 1024 x 1024 RGB: {openjpeg:.2f} s; pipeline / OpenJPEG: {total / openjpeg:.0f}x"
    )
    print(f"Hausdorff PSNR vs the original: {metrics.hausdorff_psnr(mesh, rebuilt):.2f} dB")


if __name__ == "__main__":
    main()
