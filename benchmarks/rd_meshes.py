"""Hausdorff PSNR of geometry-image coding, bandelets against wavelets, on the shared meshes.

For each mesh of ``../shared/data/meshes`` named on the command line: the spherical
parameterization and the N x N geometry image (time and area distortion), the PSNR of the
geometry-image mesh against the original (remeshing alone), then for each transform and
target bits per original vertex a real .bdl file (bytes -> bits per vertex), its decoded
mesh and its Hausdorff PSNR against the geometry-image mesh (compression alone) and against
the original, and the BD-PSNR of bandelets over wavelets. ``--variants`` compares coder options
(:data:`VARIANTS`), each also against the plain wavelet coder (no local frames, symmetric
extension).

``--ceiling 256,512`` prints instead, for each mesh, the parameterization (levels, steps, time,
area distortion) and the uncoded geometry images of those sides against the original (Hausdorff
PSNR, area over the original's); ``--draco 6,8,10`` adds Draco files at those quantization bits
(level 10) and ours of the same size (the default coder, its side chosen for the rate), then
ours at ``--bpv`` (decoded to the original's vertex count, as ``mesh-decode`` does by default)
beside Draco's best file of at most our file's size.

    python benchmarks/rd_meshes.py [fandisk.off bunny.off ...] [--size 256] [--bpv 2,4,8,16]
        [--variants default,plain]
    python benchmarks/rd_meshes.py arm.obj horse_quad.obj --ceiling 256,512 [--draco 6,7,8,10,12 --bpv 1,2,8]
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
#: Options of encode_mesh compared by --variants ("default": its defaults).
VARIANTS = {
    "default": {},
    "restored": {"restore": True},
    "no-frames": {"frames": False},
    "no-frames-restored": {"frames": False, "restore": True},
    "symmetric": {"extension": "symmetric"},
    "plain": {"frames": False, "extension": "symmetric"},
    "weight1": {"normal_weight": 1.0},
    "weight3": {"normal_weight": 3.0},
    "weight4": {"normal_weight": 4.0},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", nargs="*", default=["fandisk.off", "bunny.off"])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--bpv", default="2,4,8,16")
    parser.add_argument("--variants", default="default", help=f"comma-separated, of {', '.join(VARIANTS)}")
    parser.add_argument("--ceiling", default="", help="sides of uncoded geometry images to measure")
    parser.add_argument("--draco", default="", help="Draco quantization bits to compare at the same size")
    args = parser.parse_args()
    if args.ceiling or args.draco:
        if not MESHES.is_dir():
            sys.exit(f"{MESHES} is absent: this benchmark needs the shared test meshes")
        for name in args.meshes:
            ceiling_and_draco(name, args)
        return
    variants = args.variants.split(",")
    if not set(variants) <= set(VARIANTS):
        sys.exit(f"unknown variant in {args.variants}; choose from {', '.join(VARIANTS)}")
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
        for variant, transform in ((v, t) for v in variants for t in ("bandelet", "wavelet")):
            for bpv in (float(b) for b in args.bpv.split(",")):
                data = codec.encode_mesh(
                    mesh, image=image.positions, bits_per_vertex=bpv, transform=transform, **VARIANTS[variant]
                )
                decoded = codec.decode_mesh(data)
                real = 8 * len(data) / len(mesh.vertices)
                alone = metrics.hausdorff_psnr(remeshed, decoded)
                total = metrics.hausdorff_psnr(mesh, decoded)
                curves.setdefault((variant, transform), []).append((real, alone))
                print(
                    f"  {variant:9s} {transform:8s} target {bpv:5g} b/v: {len(data):7d} bytes = "
                    f"{real:6.2f} b/v, PSNR vs geometry image {alone:6.2f} dB, vs original {total:6.2f} dB"
                )
        if len(args.bpv.split(",")) < 4:
            continue
        for variant in variants:
            b, w = np.array(curves[variant, "bandelet"]), np.array(curves[variant, "wavelet"])
            gain = bd_psnr(b[:, 0], b[:, 1], w[:, 0], w[:, 1])
            print(f"  {variant}: BD-PSNR of bandelets over wavelets (vs geometry image): {gain:+.2f} dB")
            if "plain" in variants:
                p = np.array(curves["plain", "wavelet"])
                for transform, c in (("bandelet", b), ("wavelet", w)):
                    gain = bd_psnr(c[:, 0], c[:, 1], p[:, 0], p[:, 1])
                    print(f"  {variant}: BD-PSNR of {transform}s over plain wavelets: {gain:+.2f} dB")


def openjpeg_seconds() -> float:
    """Seconds of OpenJPEG's lossless encoding of a 1024 x 1024 RGB image: the yardstick of the
    times on a shared machine."""
    import imagecodecs

    picture = (np.random.default_rng(0).random((1024, 1024, 3)) * 255).astype(np.uint8)
    start = time.perf_counter()
    imagecodecs.jpeg2k_encode(picture, level=0)
    return time.perf_counter() - start


def ceiling_and_draco(name: str, args) -> None:
    """Print the parameterization, the uncoded ceilings and the comparison with Draco of a mesh."""
    from bandelets.surfaces import draco

    mesh = codec.load_mesh(MESHES / name)
    vertices = len(mesh.vertices)
    start = time.perf_counter()
    spherical = codec.map_to_sphere(mesh)
    seconds = time.perf_counter() - start
    distortion = {k: round(float(v), 3) for k, v in spherical.distortion.items()}
    print(
        f"{name}: {vertices} vertices; parameterization {seconds:.1f} s "
        f"({seconds / openjpeg_seconds():.0f}x OpenJPEG lossless 1024^2 RGB, timed now); "
        f"distortion {distortion}",
        flush=True,
    )
    for side in (int(n) for n in args.ceiling.split(",") if n):
        remeshed = mesh_from_image(codec.sample_geometry_image(spherical, side).positions)
        psnr = metrics.hausdorff_psnr(mesh, remeshed)
        print(
            f"  uncoded {side} x {side}: {psnr:6.2f} dB, area {remeshed.area / mesh.area:.4f} of the original"
        )
    if not args.draco:
        return
    for bits in (int(b) for b in args.draco.split(",")):
        data = draco._encode_once(np.asarray(mesh.vertices), np.asarray(mesh.faces, np.uint32), bits)
        theirs = metrics.hausdorff_psnr(mesh, draco.decode(data))
        ours_data = codec.encode_mesh(mesh, n_bytes=len(data), spherical=spherical)
        ours = metrics.hausdorff_psnr(mesh, codec.decode_mesh(ours_data))
        print(
            f"  draco {bits:2d} bits: {len(data):6d} bytes = {8 * len(data) / vertices:5.2f} b/v, "
            f"{theirs:6.2f} dB; "
            f"ours {len(ours_data):6d} bytes: {ours:6.2f} dB ({ours - theirs:+.2f})",
            flush=True,
        )
    for bpv in (float(b) for b in args.bpv.split(",")):
        try:
            data = codec.encode_mesh(mesh, bits_per_vertex=bpv, spherical=spherical)
        except ValueError as err:  # a target below the smallest file (the 502-vertex knight at 1 b/v)
            print(f"  ours at {bpv:g} b/v: {err}")
            continue
        decoded = codec.decode_mesh(data)
        psnr = metrics.hausdorff_psnr(mesh, decoded)
        try:  # Draco's best file of at most the same size
            theirs = draco.encode(mesh, len(data))
            score = metrics.hausdorff_psnr(mesh, draco.decode(theirs))
            versus = f"; draco {len(theirs):6d} bytes: {score:6.2f} dB"
        except ValueError:
            versus = "; draco: no file that small"
        print(
            f"  ours at {bpv:g} b/v: {len(data):6d} bytes = {8 * len(data) / vertices:5.2f} b/v, "
            f"{psnr:6.2f} dB ({len(decoded.vertices)} vertices){versus}",
            flush=True,
        )


if __name__ == "__main__":
    main()
