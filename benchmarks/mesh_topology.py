"""Meshes the spherical path refuses (open, any genus, several parts) against Draco.

For each mesh: Draco's two smallest files (quantization 6 and 7, compression level 10), and
ours (``bandelets.surfaces.codec.encode_mesh``, the multi-chart route) asked for Draco's byte
count, so that our file is never larger (it lands within 3 % below). Hausdorff PSNR (both
sides, bounding-box diagonal, 200,000 samples each way) of each decoded file against the input,
and the counts of components and boundary loops of the input and of our decoded mesh, both
welded by position. The meshes: fertility.off (genus 4) and rocker-arm.obj (genus 1) of
``../shared/data/meshes``, and three made from trimesh's primitives: a torus, a sphere cut open
(faces with z > 0.5 removed) and two spheres in one mesh; and two made from the shared ones:
the bunny cut open (its faces above 80 % of its height removed), the bunny and the fandisk in
one mesh.

    PYTHONPATH=src python benchmarks/mesh_topology.py [--meshes fertility.off torus ...]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from bandelets.surfaces import codec, draco, metrics

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"
MADE = ("torus", "cut-sphere", "two-spheres", "open-bunny", "bunny+fandisk")


def made(name: str):
    """A test mesh from trimesh's primitives."""
    import trimesh

    if name == "open-bunny":  # a scan with holes: the faces above 80 % of the height removed
        bunny = codec.load_mesh(MESHES / "bunny.off")
        top = bunny.bounds[0, 1] + 0.8 * (bunny.bounds[1, 1] - bunny.bounds[0, 1])
        cut = trimesh.Trimesh(bunny.vertices, bunny.faces[bunny.triangles_center[:, 1] < top])
        cut.remove_unreferenced_vertices()
        return cut
    if name == "bunny+fandisk":  # two shared meshes in one file, side by side
        bunny, fandisk = codec.load_mesh(MESHES / "bunny.off"), codec.load_mesh(MESHES / "fandisk.off")
        fandisk.apply_scale(bunny.scale / fandisk.scale)
        fandisk.apply_translation([bunny.bounds[1, 0] - fandisk.bounds[0, 0] + 0.1 * bunny.scale, 0, 0])
        return trimesh.util.concatenate([bunny, fandisk])
    if name == "torus":
        return trimesh.creation.torus(1.0, 0.35, major_sections=96, minor_sections=32)
    sphere = trimesh.creation.icosphere(4)
    if name == "cut-sphere":
        cut = trimesh.Trimesh(
            sphere.vertices, sphere.faces[~np.any(sphere.vertices[sphere.faces][:, :, 2] > 0.5, 1)]
        )
        cut.remove_unreferenced_vertices()
        return cut
    other = trimesh.creation.icosphere(4).apply_scale(0.7).apply_translation([2.5, 0, 0])
    return trimesh.util.concatenate([sphere, other])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", nargs="*", default=["fertility.off", "rocker-arm.obj", *MADE])
    args = parser.parse_args()
    print(
        "| mesh | vertices | route | Draco q | Draco bpv | Draco dB | ours bpv | ours dB | lead | "
        "components in/out | loops in/out | encode s (wall / CPU) |"
    )
    print("| --- " * 12 + "|")
    for name in args.meshes:
        if name in MADE:
            mesh = made(name)
        elif (MESHES / name).is_file():
            mesh = codec.load_mesh(MESHES / name)
        else:
            print(f"| {name} | absent ({MESHES}) |")
            continue
        n_vertices = len(mesh.vertices)
        topo_in = metrics.topology(mesh)[1:]
        for bits in (6, 7):
            reference = draco._encode_once(np.asarray(mesh.vertices), np.asarray(mesh.faces, np.uint32), bits)
            theirs = metrics.hausdorff_psnr(mesh, draco.decode(reference))
            start, start_cpu = time.perf_counter(), time.process_time()
            data = codec.encode_mesh(mesh, n_bytes=len(reference))
            seconds, cpu = time.perf_counter() - start, time.process_time() - start_cpu
            decoded = codec.decode_mesh(data)
            ours = metrics.hausdorff_psnr(mesh, decoded)
            topo_out = metrics.topology(decoded)[1:]
            route = {b"BDLC": "charts", b"BDLP": "parts"}.get(data[:4], "sphere")
            print(
                f"| {name} | {n_vertices} | {route} | {bits} | {8 * len(reference) / n_vertices:.2f} | "
                f"{theirs:.2f} | {8 * len(data) / n_vertices:.2f} | {ours:.2f} | {ours - theirs:+.2f} | "
                f"{topo_in[0]}/{topo_out[0]} | {topo_in[1]}/{topo_out[1]} | {seconds:.1f} / {cpu:.1f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
