"""How far a smooth surface through a coarse mesh's vertices is from the mesh's own flat faces.

The Hausdorff PSNR of a coded mesh is measured against the original, flat triangles included.
On a mesh of few vertices those facets are far from any smooth surface: this prints, for each
mesh of ``../shared/data/meshes`` named, the Hausdorff PSNR (200,000 samples each way) against
the original of its subdivision surfaces, two steps of Loop's (approximating) and of the
modified butterfly (interpolating: the original vertices stay where they are). A geometry image
coded at a few bits per vertex decodes to a smooth surface; where these figures are below a
target, no such surface reaches it, however its samples are coded.

    python benchmarks/mesh_facets.py [horse_quad.obj decimated-knight.off ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from bandelets.surfaces import codec, metrics

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"


def main() -> None:
    import pymeshlab
    import trimesh

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", nargs="*", default=["horse_quad.obj", "decimated-knight.off", "cow.off"])
    args = parser.parse_args()
    if not MESHES.is_dir():
        sys.exit(f"{MESHES} is absent: this benchmark needs the shared test meshes")
    for name in args.meshes:
        mesh = codec.load_mesh(MESHES / name)
        loop = trimesh.Trimesh(*trimesh.remesh.subdivide_loop(mesh.vertices, mesh.faces, iterations=2))
        meshset = pymeshlab.MeshSet()
        meshset.add_mesh(pymeshlab.Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces, np.int32)))
        meshset.meshing_surface_subdivision_butterfly(iterations=2, threshold=pymeshlab.PercentageValue(0))
        out = meshset.current_mesh()
        butterfly = trimesh.Trimesh(out.vertex_matrix(), out.face_matrix(), process=False)
        smooth = [metrics.hausdorff_psnr(mesh, surface) for surface in (loop, butterfly)]
        print(
            f"{name}: {len(mesh.vertices)} vertices; against the original: "
            f"Loop x2 {smooth[0]:.2f} dB, butterfly x2 {smooth[1]:.2f} dB",
            flush=True,
        )


if __name__ == "__main__":
    main()
