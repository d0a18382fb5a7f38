"""Peak memory per face of the mesh path: checks, spherical parameterization and a small encode.

Each mesh (one of ``../shared/data/meshes``, refined by Loop subdivision to reach larger sizes)
runs in a fresh process: loaded and subdivided, the numba kernels loaded by a tiny encode, then
the peak resident memory is reset (Linux ``/proc/self/clear_refs``) and
``encode_mesh(mesh, size=64)`` (checks, the coarse-to-fine parameterization, sampling, coding)
runs; the peak above the resident memory just before it, over the face count, is what
:data:`bandelets.surfaces.checks.MEMORY_PER_FACE` must cover.

    python benchmarks/mesh_memory.py [--meshes bunny.off:1,bunny.off:2,arm.obj:1]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"

_CHILD = """
import sys, numpy as np, bandelets
from bandelets.surfaces import codec
mesh = codec.load_mesh(sys.argv[1])
mesh = mesh.subdivide_loop(int(sys.argv[2])) if int(sys.argv[2]) else mesh
bandelets.encode(np.random.default_rng(0).normal(size=(32, 32, 3)), bpp=2.0, kind='geometry-image')
def status(key):
    return int([line for line in open('/proc/self/status') if line.startswith(key)][0].split()[1]) * 1024
before = status('VmRSS')
open('/proc/self/clear_refs', 'w').write('5')
codec.encode_mesh(mesh, size=64)
print(len(mesh.faces), before, status('VmHWM'))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--meshes", default="bunny.off:1,arm.obj:1,bunny.off:2", help="NAME:LOOP_STEPS, comma-separated"
    )
    args = parser.parse_args()
    if not MESHES.is_dir():
        sys.exit(f"{MESHES} is absent: this benchmark needs the shared test meshes")
    from bandelets.surfaces.checks import MEMORY_PER_FACE

    print(f"MEMORY_PER_FACE = {MEMORY_PER_FACE} B")
    for item in args.meshes.split(","):
        name, steps = item.split(":")
        command = [sys.executable, "-c", _CHILD, str(MESHES / name), steps]
        out = subprocess.run(command, capture_output=True, text=True, check=True)
        faces, before, peak = (int(x) for x in out.stdout.split()[-3:])
        print(
            f"{name} Loop x{steps}: {faces} faces, peak {peak / 2**20:.0f} MiB, "
            f"{(peak - before) / 2**20:.0f} MiB above the loaded mesh: {(peak - before) / faces:.0f} B/face",
            flush=True,
        )


if __name__ == "__main__":
    main()
