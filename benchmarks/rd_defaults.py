"""BD-PSNR of the defaults over AVIF, and over an earlier run, on every normal map of issue 15.

    python benchmarks/rd_defaults.py --save out/rd-defaults-main.json        # on main
    python benchmarks/rd_defaults.py --against out/rd-defaults-main.json     # on a branch

(from the repository root; 4 to 10 minutes on the 2-core machine.) The maps: the generated
crease (256 and 512), bumps (256) and bevel (256 and 512, 8-bit samples), the shared real maps
of ``../shared/data/normal-maps`` (read as ``benchmarks/rd_normal_maps.py`` reads them, 8-bit)
and the normal maps of the fandisk and bunny meshes (``make_geometry_image(load_mesh(MESH), 256).normals``, as
``benchmarks/rd_surfaces.py --only mesh-normals`` makes them, given as floats; any other mesh of
``--meshes`` by its name, ``--maps screwdriver arm``, at another size as ``arm@512``), and the
object-space maps rendered from them (``fandisk-top@256``, ``bunny-top@256``: 16-bit samples,
``rd_normal_maps.py --rendered``; ``fandisk-oblique`` and 512 on request); a map whose
file is absent is skipped with a message. For each, at 0.25 to 2 bpp,
``bandelets.encode(map, bpp=B, kind="normal-map", depth=D)`` and AVIF as
:mod:`bandelets.apps.anchors` drives it (4:4:4, identity matrix, speed 2), every point measured
from its file (bpp ``8 x bytes / pixels``, PSNR of the decoded vectors renormalised). Prints the
points and the BD-PSNR of the defaults over AVIF and, with ``--against``, over the defaults of
the run saved there (``--save`` writes this run's curves as JSON; ``--avif`` takes AVIF's curves
from such a file instead of encoding them again, which takes most of the run's time).

A point that is a lossless file (an 8-bit map under a target its lossless file fits) has an
infinite PSNR; the BD-PSNRs are those of ``benchmarks/rd_normal_maps.py``: on the finite points
over the common range, and (in brackets, over AVIF) with the lossless point kept at the other
curve's best finite PSNR, a lower bound.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import bandelets
from bandelets.apps import anchors
from bandelets.format.header import unpack
from bandelets.metrics import bd_psnr, bits_per_pixel, psnr
from bandelets.transform.normals import unit_vectors

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_normal_maps import RATES, RENDERED, _capped, load, rendered, sample  # noqa: E402

MAPS = (
    "crease@256",
    "bumps@256",
    "crease@512",
    "bevel@256",
    "bevel@512",
    "acacia_door_bottom_n",
    "lava_flow_n",
    "fandisk",
    "bunny",
    "fandisk-top@256",
    "bunny-top@256",
)
#: The shared meshes in ``MAPS``; any other genus-0 mesh of ``--meshes`` is taken by its name
#: without suffix (``--maps screwdriver elephant``).
MESH_MAPS = ("fandisk", "bunny")
MESH_SUFFIXES = (".off", ".obj")


def _mesh(meshes: Path, name: str) -> Path | None:
    """The mesh file ``name`` of ``meshes`` (with one of :data:`MESH_SUFFIXES`), or None."""
    return next((meshes / f"{name}{s}" for s in MESH_SUFFIXES if (meshes / f"{name}{s}").is_file()), None)


def _maps(names, real: Path, meshes: Path):
    """``name -> (unit vectors, depth)`` of the maps ``names`` whose source is present."""
    for name in names:
        base, _, size = name.partition("@")  # a size after "@", else the default of each kind
        if size and base in RENDERED:
            if (made := rendered(base, int(size), meshes)) is not None:
                yield name, made
        elif mesh := _mesh(meshes, base):
            from bandelets.surfaces.codec import load_mesh, make_geometry_image

            normals = make_geometry_image(load_mesh(mesh), int(size or 256)).normals
            yield name, (np.asarray(normals, np.float32).astype(np.float64), 0)
        elif size:
            yield name, sample(base, int(size))
        elif base in MESH_MAPS:
            print(f"skipping {name}: no {meshes / base}.off or .obj")
        elif (real / f"{name}.png").is_file():
            yield name, (load(real / f"{name}.png").astype(np.float64) / 255.0 * 2.0 - 1.0, 8)
        else:
            print(f"skipping {name}: no {real / name}.png")


def _curve(vectors: np.ndarray, depth: int, codec: str) -> list[tuple[float, float]]:
    points = []
    for rate in RATES:
        if codec == "bandelets":
            data = bandelets.encode(vectors, bpp=rate, kind="normal-map", depth=depth)
            decoded = bandelets.decode(data)
            if unpack(data)[0].transform == "lossless":  # checked exact, as rd_normal_maps does
                if not np.array_equal(decoded, vectors):
                    raise RuntimeError("a lossless .bdl file does not decode to its source")
                points.append((bits_per_pixel(len(data), vectors.shape), float("inf")))
                continue
        else:
            data = anchors.encode(vectors, rate, codec, "normal-map", depth)
            decoded = anchors.decode(data, codec, vectors, "normal-map", depth)
        points.append(
            (bits_per_pixel(len(data), vectors.shape), psnr(unit_vectors(vectors), decoded, "normal-map"))
        )
    return points


def _bd(ours, theirs) -> float:
    """BD-PSNR on the finite points of both curves."""
    return bd_psnr(*zip(*_finite(ours), strict=True), *zip(*_finite(theirs), strict=True))


def _finite(points):
    return [(b, p) for b, p in points if np.isfinite(p)]


def _rows(points) -> list[dict]:
    return [{"bpp": b, "psnr": p} for b, p in points]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--maps", nargs="+", default=list(MAPS), help=f"maps (default: {' '.join(MAPS)})")
    parser.add_argument("--real", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--meshes", type=Path, default=Path("../shared/data/meshes"))
    parser.add_argument("--save", type=Path, help="write this run's curves here (JSON)")
    parser.add_argument("--against", type=Path, help="curves of an earlier run (--save) to compare with")
    parser.add_argument(
        "--avif", type=Path, help="AVIF's curves from an earlier run (--save), where it has them"
    )
    args = parser.parse_args()
    earlier = json.loads(args.against.read_text()) if args.against else {}
    kept = json.loads(args.avif.read_text()) if args.avif else {}
    curves = {}
    for name, (vectors, depth) in _maps(args.maps, args.real, args.meshes):
        ours = _curve(vectors, depth, "bandelets")
        avif = [tuple(p) for p in kept[name]["avif"]] if name in kept else _curve(vectors, depth, "avif")
        curves[name] = {"bandelets": ours, "avif": avif}
        points = " ".join(f"{p:.2f} ({b:.3f})" for b, p in ours)
        line = f"{name}: {points}; over AVIF {_bd(ours, avif):+.2f} dB"
        if len(_finite(ours)) < len(ours):
            line += f" ({_capped(_rows(ours), _rows(avif))} with the lossless point capped)"
        if name in earlier:
            line += f", over the earlier run {_bd(ours, earlier[name]['bandelets']):+.3f} dB"
            line += f" (which was {_bd(earlier[name]['bandelets'], avif):+.2f} over AVIF)"
        print(line, flush=True)
    if args.save:
        args.save.parent.mkdir(parents=True, exist_ok=True)
        args.save.write_text(json.dumps(curves))


if __name__ == "__main__":
    main()
