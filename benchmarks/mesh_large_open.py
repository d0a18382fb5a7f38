"""Time and memory of coding a 100k-vertex open scan on the multi-chart route (target: encode under a minute).

The mesh: a shared scan refined by Loop subdivision (default: cheburashka.off, 6,669 vertices,
twice: 106,700), then cut open (its faces above ``--cut`` of its height removed: a hole as a scan
has). ``encode_mesh`` at ``--bpv`` bits per vertex with the defaults of ``mesh-encode``, then
``decode_mesh``; wall and CPU seconds of each (CPU counts every thread: up to twice the wall time
on the two cores; the machine is shared, so the wall time shows its load), the peak resident
memory of the process (the loaded mesh included) against the default ``max_memory``, the
Hausdorff PSNR of the decoded mesh, and its components and boundary loops against the input's.

    PYTHONPATH=src python benchmarks/mesh_large_open.py [--mesh cheburashka.off] [--subdivide 2] [--bpv 4]
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

import bandelets
from bandelets.format.fields import MAX_MEMORY
from bandelets.surfaces import metrics
from bandelets.surfaces.codec import decode_mesh, encode_mesh, load_mesh

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mesh_topology import MESHES  # noqa: E402


def main() -> None:
    import trimesh

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", default="cheburashka.off")
    parser.add_argument("--subdivide", type=int, default=2)
    parser.add_argument("--cut", type=float, default=0.9, help="share of the height kept (default 0.9)")
    parser.add_argument("--bpv", type=float, default=4.0)
    args = parser.parse_args()
    if not (MESHES / args.mesh).is_file():
        sys.exit(f"{MESHES / args.mesh} is absent: this benchmark needs the shared test meshes")
    bandelets.encode(np.random.default_rng(0).normal(size=(32, 32, 3)), bpp=2.0, kind="geometry-image")
    mesh = load_mesh(MESHES / args.mesh).subdivide_loop(args.subdivide)
    axis = int(np.argmax(mesh.extents))
    top = mesh.bounds[0, axis] + args.cut * mesh.extents[axis]
    mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[mesh.triangles_center[:, axis] < top])
    mesh.remove_unreferenced_vertices()
    print(
        f"{args.mesh} Loop x{args.subdivide}, cut at {args.cut:.0%} of its height: "
        f"{len(mesh.vertices)} vertices, {len(mesh.faces)} faces, "
        f"components/loops {metrics.topology(mesh)[1:]}"
    )
    start, cpu = time.perf_counter(), time.process_time()
    data = encode_mesh(mesh, bits_per_vertex=args.bpv)
    print(
        f"encode: {time.perf_counter() - start:.1f} s wall, {time.process_time() - cpu:.1f} s CPU, "
        f"{len(data)} bytes ({8 * len(data) / len(mesh.vertices):.2f} bits per vertex)",
        flush=True,
    )
    start, cpu = time.perf_counter(), time.process_time()
    decoded = decode_mesh(data)
    print(f"decode: {time.perf_counter() - start:.1f} s wall, {time.process_time() - cpu:.1f} s CPU")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(
        f"peak resident memory {peak / 2**20:.0f} MiB (default max_memory {MAX_MEMORY / 2**20:.0f} MiB); "
        f"load average {os.getloadavg()[0]:.1f}"
    )
    print(
        f"Hausdorff PSNR {metrics.hausdorff_psnr(mesh, decoded):.2f} dB; "
        f"components/loops decoded {metrics.topology(decoded)[1:]}"
    )


if __name__ == "__main__":
    main()
