"""Command line: argument parsing and error reporting only.

Every command imports the codec (numba, imagecodecs) when it runs, so that
``bandelets --help`` starts at once; the choices come from :mod:`bandelets.format.header`, which
imports nothing. Any error the user can cause ends in one line
``bandelets: error: ...`` on stderr and exit status 2; outputs are written to a temporary
file and renamed, so a failed command leaves nothing behind.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

from ..format.fields import (
    DEFAULT_NORMAL_WEIGHT,
    DEFAULT_TRANSFORM_1D,
    DEFAULT_WAVELET,
    EXTENSIONS,
    KINDS,
    TRANSFORMS,
    TRANSFORMS_1D,
    WAVELETS,
    Kind,
)
from . import deliver

__all__ = ["main"]

FORMATS = "PNG (8/16-bit), TIFF (8/16-bit, float), OpenEXR (.exr) or .npy"
# bandelets.io.files.SUFFIXES and the refused ones: not names for a .bdl file.
IMAGE_SUFFIXES = (".png", ".npy", ".exr", ".tif", ".tiff", ".jpg", ".jpeg", ".webp")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, like every other error
        raise _UsageError(message)


class _UsageError(Exception):
    pass


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="bandelets",
        description="Compress images, normal maps and geometry "
        "images with geometric bandelets (Peyre and Mallat 2005).",
    )
    parser.add_argument("--version", action="version", version="bandelets 0.1.0")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser(
        "encode",
        help=f"compress an image ({FORMATS}) into a .bdl file",
        description=f"Compress an image into a .bdl file. Inputs: {FORMATS}; gray, RGB, RGBA (alpha "
        "dropped), or H x W x C arrays. JPEG and WebP inputs are refused (lossy: their artefacts "
        "would be coded as detail). Prints a summary line on stderr (-q: none).",
    )
    p.add_argument("input", help=f"{FORMATS}: integer samples map to [0, 1] ([-1, 1] for normal maps)")
    p.add_argument("output", help="the .bdl file to write")
    target = p.add_mutually_exclusive_group()
    target.add_argument("--bpp", type=float, help="target rate in bits per pixel (default 1)")
    target.add_argument("--threshold", type=float, help="quantization threshold T")
    target.add_argument(
        "--psnr", type=float, help="target PSNR in dB, of the decoded image at the input's bit depth"
    )
    target.add_argument(
        "--max-angle",
        type=float,
        metavar="DEG",
        help="normal maps: the largest 99th percentile of the angle between input and decoded normals, "
        "in degrees (the tail, where creases show artefacts; the mean follows --psnr)",
    )
    target.add_argument(
        "--lossless",
        action="store_true",
        help="code the input's 8 or 16-bit samples exactly, every channel (PNG, TIFF; the decoded file "
        "has the same samples). By default a --bpp target that the lossless file fits gets it",
    )
    p.add_argument(
        "--no-lossless",
        action="store_true",
        help="never write the lossless file in place of a --bpp target (a lossy file of the rate asked)",
    )
    p.add_argument("--transform", choices=TRANSFORMS, default="bandelet")
    p.add_argument(
        "--kind",
        choices=KINDS,
        default="image",
        help="image (default: values kept as they are), normal-map (RGB vectors, renormalised to unit "
        "length: use image to keep their lengths) or geometry-image",
    )
    p.add_argument(
        "--xy",
        action="store_true",
        help="normal maps: code red and green as x, y and rebuild z (BC5-style maps whose blue is unused "
        "or holds something else); a two-channel input always is x, y. Decodes to the layout given",
    )
    p.add_argument(
        "--wavelet",
        default=DEFAULT_WAVELET,
        help=f"{', '.join(WAVELETS)} (default {DEFAULT_WAVELET}), or auto (the better of cdf97 and haar, "
        "in twice the time)",
    )
    p.add_argument(
        "--transform-1d",
        choices=TRANSFORMS_1D,
        default=DEFAULT_TRANSFORM_1D,
        help=f"1D transform along the directions (default {DEFAULT_TRANSFORM_1D}: alpert2 has two vanishing "
        "moments, haar one)",
    )
    p.add_argument(
        "--no-restore",
        action="store_true",
        help="decode by plain dequantization: no restoration by the decoder (faster to encode and decode)",
    )
    p.add_argument(
        "--no-loop-filter",
        action="store_true",
        help="write no loop filter (a few dozen bytes the encoder fits so that the decoder sharpens the "
        "restored image; by default written where it pays)",
    )
    p.add_argument(
        "--lifting",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="lift the two finest CDF 9/7 levels along directions chosen per block (better on creases at "
        "an angle; default: on for normal maps where the directions pay)",
    )
    p.add_argument(
        "--riesz",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="code a normal map's two channels as their Riesz pair: one channel along the gradients of a "
        "height, one across them (maps baked from height fields; default: where it pays)",
    )
    p.add_argument(
        "--tile",
        type=int,
        default=0,
        metavar="N",
        help="code an image with a side above N pixels in independent tiles of about N x N, two at a time "
        "(bounded memory at any size, a region decodes alone; default: tiles of 512 only for an image "
        "that would not fit --max-memory in one piece)",
    )
    deliver.add_green_option(p, decoding=False)
    _common(p)

    p = sub.add_parser("decode", help=f"decode a .bdl file into {FORMATS}")
    p.add_argument("input")
    p.add_argument(
        "output",
        help=".png or .tif (the source's bit depth: 8, 16, or 16-bit PNG and float TIFF for float "
        "sources), .exr or .npy (float32); .ktx2 or .dds (a normal map, for the GPU)",
    )
    deliver.add_decode_options(p)
    p.add_argument(
        "--no-restore",
        action="store_true",
        help="skip the restoration and the loop filter the file asks for: a faster decode of lower quality "
        "(a preview)",
    )
    _common(p)

    p = sub.add_parser("info", help="print what a .bdl file holds, as one JSON object")
    p.add_argument("input")

    p = sub.add_parser("demo", help="compress a generated normal map with bandelets and wavelets")
    p.add_argument("--size", type=int, default=512, help="side of the generated map (default 512)")
    p.add_argument("--rates", default="0.25,0.5,1,2", help="target bpp list (default 0.25,0.5,1,2)")
    p.add_argument("--out", default="bandelets-demo", help="folder for the files (default bandelets-demo)")

    p = sub.add_parser("rd", help="rate-distortion curves and BD-PSNR against other codecs")
    p.add_argument(
        "inputs",
        nargs="*",
        metavar="INPUT",
        help="PNG, .npy or sample:NAME[@SIZE] (crease, bumps, bevel, edge-step, edge-tangent), or closed "
        "genus-0 meshes (OBJ, PLY, OFF, STL); with --decay, default sample:edge-step sample:edge-tangent",
    )
    p.add_argument("--kind", choices=KINDS, default="image", help="kind of the file inputs (default image)")
    p.add_argument(
        "--rates",
        help="target bpp list (default 0.125,0.25,0.5,1,2; with --decay 1/64 to 1); "
        "for meshes bits per vertex (default 2,4,8,16)",
    )
    p.add_argument(
        "--codecs",
        help="from bandelet,wavelet,jpeg2000,avif,jpegxl (default all; with --decay bandelet,wavelet); "
        "for meshes from bandelet,wavelet,draco (default all)",
    )
    p.add_argument(
        "--size",
        type=int,
        help="side of the geometry image of meshes (default: chosen for each rate, as mesh-encode does)",
    )
    p.add_argument("--out", default="rd", help="folder for the files, rd.csv and rd.png (default rd)")
    p.add_argument("--decay", action="store_true", help="also fit the decay exponent of log MSE vs log bits")

    p = sub.add_parser("show", help="draw the quadtrees and directions of a .bdl file (paper figure 6)")
    p.add_argument("input")
    p.add_argument("output", help="the PNG to write")
    p.add_argument("-f", "--force", action="store_true", help="overwrite an existing output")

    p = sub.add_parser("mesh-encode", help="compress a closed genus-0 mesh as a spherical geometry image")
    p.add_argument("input", help="triangle mesh (OBJ, PLY, OFF, STL, ...)")
    p.add_argument("output", help="the .bdl file to write")
    p.add_argument(
        "--size",
        type=int,
        help="side of the geometry image, even (default: the largest of 64, 128, 256, 512, 1024 that "
        "gets at least 0.1 bit per pixel of a --bits-per-vertex or --bytes target; 256 with --bpp)",
    )
    target = p.add_mutually_exclusive_group()
    target.add_argument("--bpp", type=float, help="bits per geometry-image pixel (default 1)")
    target.add_argument("--bits-per-vertex", type=float, help="bits per vertex of the input mesh")
    target.add_argument("--bytes", type=int, help="size of the whole file")
    p.add_argument("--transform", choices=TRANSFORMS, default="bandelet")
    p.add_argument(
        "--no-frames", action="store_true", help="code the positions as they are, not in local frames"
    )
    p.add_argument(
        "--normal-weight",
        type=float,
        default=DEFAULT_NORMAL_WEIGHT,
        metavar="W",
        help="precision of the normal component over the tangential ones in local frames "
        f"(default {DEFAULT_NORMAL_WEIGHT:g})",
    )
    p.add_argument(
        "--extension",
        choices=EXTENSIONS,
        default="spherical",
        help="wavelet boundary extension (default spherical: the image's edges as glued on the sphere)",
    )
    p.add_argument(
        "--restore",
        action="store_true",
        help="let the decoder restore the positions (raises the Hausdorff PSNR of CAD meshes, "
        "may lower that of scanned ones; see BENCHMARKS.md)",
    )
    p.add_argument("-f", "--force", action="store_true", help="overwrite an existing output")

    p = sub.add_parser("mesh-decode", help="rebuild the closed mesh of a geometry-image .bdl file")
    p.add_argument("input")
    p.add_argument("output", help=".obj, .ply or .off")
    size = p.add_mutually_exclusive_group()
    size.add_argument(
        "--vertices",
        type=int,
        metavar="N",
        help="simplify the mesh to N vertices (default: the original mesh's count, stored in the file)",
    )
    size.add_argument(
        "--full", action="store_true", help="write the whole grid: one vertex per geometry-image pixel"
    )
    p.add_argument("-f", "--force", action="store_true", help="overwrite an existing output")

    p = sub.add_parser(
        "geometry-image", help="spherical geometry image (and normal map) of a closed genus-0 mesh"
    )
    p.add_argument("input", help="triangle mesh (OBJ, PLY, OFF, STL, ...)")
    p.add_argument("output", nargs="?", help="the .npy to write (n x n x 3 float32 positions)")
    p.add_argument("--size", type=int, default=256, help="side of the image, even (default 256)")
    p.add_argument(
        "--report",
        action="store_true",
        help="print the parameterization's stretch, sample area ratio, and the uncoded image's "
        "Hausdorff PSNR and area against the original",
    )
    p.add_argument("--normals", help="also write the unit normals: 16-bit .png or float32 .npy")
    p.add_argument("-f", "--force", action="store_true", help="overwrite existing outputs")

    p = sub.add_parser("batch", help="compress folders of images and meshes on Dask (local or a cluster)")
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="files, folders (recursive) and globs")
    p.add_argument("--out", required=True, metavar="DIR", help="folder of the .bdl files and the report")
    target = p.add_mutually_exclusive_group()
    target.add_argument("--bpp", type=float, help="target rate of the images (default 1), or of meshes")
    target.add_argument("--psnr", type=float, help="target PSNR of the images in dB")
    target.add_argument("--threshold", type=float, help="quantization threshold T of the images")
    p.add_argument("--kind", choices=KINDS, default="image", help="kind of the image inputs (default image)")
    p.add_argument("--bits-per-vertex", type=float, metavar="V", help="target of the meshes")
    p.add_argument("--workers", type=int, metavar="N", help="local worker processes (default one per core)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, tcp://HOST:PORT")
    p.add_argument("--report", metavar="FILE", help="report .csv or .parquet (default DIR/report.csv)")
    p.add_argument("-f", "--force", action="store_true", help="redo files an earlier run left up to date")
    deliver.add_batch_options(p)
    return parser


def _memory(text: str) -> int:
    """Bytes of a ``--max-memory`` value: MiB, or a number with a K, M or G suffix."""
    scale = {"K": 2**10, "M": 2**20, "G": 2**30}.get(text[-1:].upper())
    try:
        value = float(text[:-1] if scale else text) * (scale or 2**20)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a size such as 512M or 4G, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"the memory limit must be positive, got {text!r}")
    return int(value)


def _common(p: argparse.ArgumentParser) -> None:
    """Options of encode and decode besides their own."""
    p.add_argument(
        "--max-memory",
        type=_memory,
        default=2 * 2**30,
        metavar="SIZE",
        help="refuse an image whose coding would need more memory (MiB, or with K, M, G; default 2G)",
    )
    p.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="nothing on stderr but errors (no summary line, no compile notice)",
    )
    p.add_argument("-f", "--force", action="store_true", help="overwrite an existing output")


def _working(quiet: bool = False) -> None:
    """Called by each command once its arguments are checked, before the codec loads: from here
    on numba may compile the kernels, and :func:`bandelets.runtime.compilation.announce` says so, unless
    ``-q`` asks for silence, as gzip's does (numba itself takes a third of a second to import:
    not for an argument error)."""
    if not quiet:
        from ..runtime.compilation import announce

        announce()


def _check_input(path: str) -> None:
    if not Path(path).is_file():
        raise ValueError(f"{path}: no such file")


def _check_output(input_path: str, output: str, force: bool) -> None:
    out = Path(output)
    if out.exists() and Path(input_path).exists() and os.path.samefile(input_path, out):
        raise ValueError(f"{output}: output would overwrite the input")
    if out.exists() and not force:
        raise ValueError(f"{output}: already exists (use --force to overwrite)")
    if not out.parent.exists() and str(out.parent):
        raise ValueError(f"{output}: folder {out.parent} does not exist")
    if out.is_dir():
        raise ValueError(f"{output}: is a folder")
    try:  # before any work: the output is written there, through a temporary file
        with tempfile.TemporaryFile(dir=out.parent):
            pass
    except OSError as err:
        raise ValueError(f"{output}: cannot write in folder {out.parent} ({err.strerror})") from None


def _check_targets(args) -> None:
    """Refuse a rate or quality target that is not a positive number, before reading anything."""
    for option in ("bpp", "threshold", "psnr", "max_angle", "bits_per_vertex", "bytes"):
        value = getattr(args, option, None)
        if value is not None and not 0 < value < float("inf"):
            raise _UsageError(f"--{option.replace('_', '-')} must be a positive number, got {value:g}")


def _encode(args) -> None:
    _check_targets(args)
    if args.lossless and args.no_lossless:
        raise _UsageError("--lossless and --no-lossless contradict each other")
    _check_input(args.input)
    _check_output(args.input, args.output, args.force)
    if Path(args.output).suffix.lower() in IMAGE_SUFFIXES:
        raise ValueError(f"{args.output}: encode writes a .bdl file; name it {Path(args.output).stem}.bdl")
    _working(args.quiet)
    start = time.perf_counter()
    from ..io.files import read_array

    array, depth = read_array(args.input, args.kind, args.max_memory)
    from ..codec.encoder import encode_with_stats
    from ..codec.options import EncodeOptions
    from ..io.files import write_atomic

    target = {"bpp": args.bpp, "threshold": args.threshold, "psnr": args.psnr, "max_angle": args.max_angle}
    if all(v is None for v in target.values()) and not args.lossless:
        target["bpp"] = 1.0
    options = EncodeOptions(
        transform=args.transform,
        kind=args.kind,
        wavelet=args.wavelet,
        transform_1d=args.transform_1d,
        depth=depth,
        restore=not args.no_restore,
        loop_filter=not args.no_loop_filter,
        progress=sys.stderr.isatty() and not args.quiet,
        max_memory=args.max_memory,
        xy=args.xy,
        lifting=args.lifting,
        riesz=args.riesz,
        tile=args.tile,
        lossless=True if args.lossless else False if args.no_lossless else None,
    )
    encoded = encode_with_stats(array, options, **target, measured=not args.quiet)
    if args.green == "down":
        if args.kind != "normal-map":
            raise _UsageError("--green is for normal maps (--kind normal-map)")
        encoded = dataclasses.replace(encoded, data=deliver.with_green(encoded.data, args.green))
    write_atomic(args.output, encoded.data)
    if not args.quiet:
        from .summary import encode_summary

        elapsed = time.perf_counter() - start
        print(
            encode_summary(
                args.input, args.output, array, depth, args.kind, args.xy, encoded, elapsed, target["bpp"]
            ),
            file=sys.stderr,
        )


def _decode(args) -> None:
    _check_input(args.input)
    _check_output(args.input, args.output, args.force)
    from ..io.files import check_suffix

    gpu = deliver.gpu_suffix(args.output)
    if not gpu:
        check_suffix(args.output, "output")
    if args.level < 0:
        raise _UsageError(f"--level is 0 or more, not {args.level}")
    _working(args.quiet)
    start = time.perf_counter()
    from ..codec.levels import prefix_header

    with _about(args.input):
        data = _read_bdl(args.input)
        progress = sys.stderr.isatty() and not args.quiet
        options = {"restore": not args.no_restore, "max_memory": args.max_memory, "progress": progress}
        decoded, added, count = deliver.write_outputs(
            data, args.output, args.level, args.mips, args.gpu, args.green, **options
        )
    if not args.quiet:
        from .summary import decode_summary

        elapsed = time.perf_counter() - start
        line = decode_summary(args.input, args.output, decoded, prefix_header(data), elapsed) + added
        print(line + (f", {count} levels" if args.mips else ""), file=sys.stderr)


@contextlib.contextmanager
def _about(path: str):
    """Name ``path`` in the message of any ValueError raised inside (a bad .bdl file)."""
    try:
        yield
    except ValueError as err:
        if str(err).startswith(f"{path}:"):
            raise
        raise ValueError(f"{path}: {err}") from None


def _read_bdl(path: str) -> bytes:
    if not Path(path).is_file():
        raise ValueError(f"{path}: no such file")
    return Path(path).read_bytes()


def _info(args) -> None:
    _check_input(args.input)
    _working()
    from ..codec.levels import level_bytes
    from ..format.container import header_of, is_tiled, read
    from ..format.fields import FORMAT_VERSION
    from ..format.header import unpack
    from ..metrics import bits_per_pixel

    data = _read_bdl(args.input)
    with _about(args.input):
        header = header_of(data)
        if is_tiled(data):
            grid, tiles = read(data)
            streams = [b"".join(s) for s in zip(*(tile()[1] for tile in tiles), strict=True)]
        else:
            streams = unpack(data)[1]
    info = {
        "width": header.width,
        "height": header.height,
        "channels": header.channels,
        "kind": header.kind,
        "transform": header.transform,
        "wavelet": header.wavelet,
        "levels": header.levels,
        "transform_1d": header.transform_1d,
        "threshold": header.threshold,
        "restoration": header.restoration,
        "lifting_levels": header.lifting,
        "riesz": header.riesz,
        "loop_filter": None
        if header.loop_filter is None
        else {
            "radius": header.loop_filter.radius,
            "cross_channel": header.loop_filter.cross,
            "square": header.loop_filter.square,
            "clip": header.loop_filter.clip,
        },
        "bytes": len(data),
        "bpp": bits_per_pixel(len(data), (header.height, header.width)),
        "bits": {
            "header": 8 * (len(data) - sum(len(s) for s in streams)),
            "quadtree": 8 * len(streams[0]),
            "geometry": 8 * len(streams[1]),
            "coefficients": 8 * len(streams[2]),
        },
        "format_version": FORMAT_VERSION,
        "level_bytes": level_bytes(data),
    }
    if is_tiled(data):
        info |= {"tile": grid.tile, "tiles": len(grid.boxes)}
    if header.kind == Kind.GEOMETRY_IMAGE:
        info |= {"extension": header.extension, "mesh_vertices": header.mesh_vertices}
    if header.kind == Kind.NORMAL_MAP:
        info |= {"layout": header.layout, "folded": header.folded, "green": header.green}
    if header.kind == Kind.GEOMETRY_IMAGE or header.frames:
        info |= {"frames": header.frames, "normal_weight": header.normal_weight}
    print(json.dumps(info))


def _demo(args) -> None:
    _working()
    from .demo import run_demo

    rates = [float(r) for r in args.rates.split(",") if r.strip()]
    if args.size < 16:
        raise ValueError(f"--size must be at least 16, got {args.size}")
    run_demo(args.size, rates, Path(args.out), progress=sys.stderr.isatty())


def _numbers(text: str, option: str) -> list[float]:
    try:
        return [float(r) for r in text.split(",") if r.strip()]
    except ValueError:
        raise ValueError(f"{option} must be a comma-separated list of numbers, got {text!r}") from None


def _rd(args) -> None:
    _working()
    from ..io.files import MESH_SUFFIXES
    from . import anchors, rd

    inputs = args.inputs or (["sample:edge-step", "sample:edge-tangent"] if args.decay else [])
    if not inputs:
        raise ValueError("give at least one INPUT (a PNG, a .npy file or sample:NAME)")
    meshes = [Path(spec).suffix.lower() in MESH_SUFFIXES for spec in inputs]
    if any(meshes) and not all(meshes):
        raise ValueError("give either images or meshes, not both")
    if meshes[0]:
        default_rates, default_codecs = "2,4,8,16", ",".join(rd.MESH_CODECS)
    elif args.decay:
        default_rates, default_codecs = "0.015625,0.03125,0.0625,0.125,0.25,0.5,1", "bandelet,wavelet"
    else:
        default_rates, default_codecs = "0.125,0.25,0.5,1,2", ",".join(rd.CODECS)
    rates = _numbers(args.rates or default_rates, "--rates")
    codecs = [c.strip() for c in (args.codecs or default_codecs).split(",") if c.strip()]
    rd.check_codecs(codecs, meshes[0])  # before the slow part: loading meshes parameterizes them
    sources = [rd.load(spec, args.kind, args.size) for spec in inputs]
    for source in sources:
        if isinstance(source, rd.MeshSource):
            from ..surfaces.geometry_image import mesh_from_image
            from ..surfaces.metrics import hausdorff_psnr

            ceilings = [
                f"{side} x {side}: {hausdorff_psnr(source.mesh, mesh_from_image(source.image(side))):.2f} dB"
                for side in sorted({source.side(rate) for rate in rates})
            ]
            print(
                f"{source.name}: {len(source.mesh.vertices)} vertices, "
                f"parameterized in {source.image_s:.1f} s; geometry images against the original "
                f"before coding: {', '.join(ceilings)}"
            )
    out = Path(args.out)
    rows = rd.run(sources, rates, codecs, out, progress=sys.stderr.isatty())
    versions = anchors.versions()
    if "draco" in codecs:
        from ..surfaces import draco

        versions["draco"] = draco.version()
    for codec, version in versions.items():
        if codec in codecs:
            print(f"{codec}: {version}")
    print(rd.format_points(rows))
    print()
    print(rd.format_summary(rows, slopes=args.decay))
    print(f"\nfiles, rd.csv and rd.png (and rd-angle.png for normal maps) in {out}/")


def _show(args) -> None:
    _check_input(args.input)
    _check_output(args.input, args.output, args.force)
    if Path(args.output).suffix.lower() != ".png":
        raise ValueError(f"{args.output}: show draws a PNG; name it {Path(args.output).stem}.png")
    _working()
    from .show import geometry_figure

    with _about(args.input):
        geometry_figure(_read_bdl(args.input), Path(args.output))


def _mesh_encode(args) -> None:
    _check_targets(args)
    _check_input(args.input)
    _check_output(args.input, args.output, args.force)
    _working()
    from ..io.files import write_atomic
    from ..surfaces.codec import encode_mesh, load_mesh

    with _about(args.input):  # the mesh's checks name what is wrong, not which file
        data = encode_mesh(
            load_mesh(args.input),
            size=args.size,
            bpp=args.bpp,
            bits_per_vertex=args.bits_per_vertex,
            n_bytes=args.bytes,
            transform=args.transform,
            frames=not args.no_frames,
            normal_weight=args.normal_weight,
            extension=args.extension,
            restore=args.restore,
        )
    write_atomic(args.output, data)


def _mesh_decode(args) -> None:
    _check_input(args.input)
    _check_output(args.input, args.output, args.force)
    file_type = Path(args.output).suffix.lower().lstrip(".")
    if file_type not in ("obj", "ply", "off"):  # bandelets.surfaces.codec.MESH_FORMATS
        raise ValueError(f"{args.output}: unsupported mesh format; use .obj, .ply or .off")
    if args.vertices is not None and args.vertices < 4:
        raise _UsageError(f"--vertices must be at least 4 (a closed mesh), got {args.vertices}")
    _working()
    from ..io.files import write_atomic
    from ..surfaces.codec import decode_mesh, mesh_bytes

    with _about(args.input):
        mesh = decode_mesh(_read_bdl(args.input), vertices="full" if args.full else args.vertices)
    write_atomic(args.output, mesh_bytes(mesh, file_type))


def _geometry_image(args) -> None:
    _check_input(args.input)
    if args.output is None and not args.report:
        raise ValueError("give an output .npy, or --report")
    outputs = ([args.output] if args.output else []) + ([args.normals] if args.normals else [])
    suffixes = ([(".npy",)] if args.output else []) + [(".png", ".npy")]
    for output, allowed in zip(outputs, suffixes, strict=False):
        _check_output(args.input, output, args.force)
        if Path(output).suffix.lower() not in allowed:
            raise ValueError(f"{output}: unsupported output format; use {' or '.join(allowed)}")
    if args.normals and args.output and Path(args.normals).resolve() == Path(args.output).resolve():
        raise ValueError(f"{args.normals}: --normals would overwrite the positions output")
    _working()
    from ..io.files import write_array
    from ..surfaces.codec import check_size, load_mesh, map_to_sphere, sample_geometry_image

    check_size(args.size)  # before the slow parameterization
    with _about(args.input):
        mesh = load_mesh(args.input)
        spherical = map_to_sphere(mesh)
        image = sample_geometry_image(spherical, args.size)
    if args.output:
        write_array(args.output, image.positions, "geometry-image", 0)
    if args.normals:
        try:
            write_array(args.normals, image.normals, "normal-map", 16)
        except BaseException:  # both outputs or neither
            if args.output:
                Path(args.output).unlink(missing_ok=True)
            raise
    if args.report:
        from ..surfaces.report import parameterization_report

        r = parameterization_report(mesh, spherical, args.size)
        print(
            f"{args.input}: {len(mesh.vertices)} vertices; stretch {r['stretch']:.3f} (1 at best); "
            f"sample areas max/min {r['sample_area_ratio']:.3g}; uncoded {args.size} x {args.size}: "
            f"Hausdorff PSNR {r['psnr']:.2f} dB, area {r['area']:.4f} of the original"
        )


def _batch(args) -> int:
    _working()
    from .batch import batch

    report = batch(
        args.inputs,
        args.out,
        bpp=args.bpp,
        psnr=args.psnr,
        threshold=args.threshold,
        kind=args.kind,
        bits_per_vertex=args.bits_per_vertex,
        workers=args.workers,
        scheduler=args.scheduler,
        report=args.report,
        force=args.force,
        progress=sys.stderr.isatty(),
    )
    if args.to:  # each file of the batch decoded beside it (bandelets.apps.deliver.ship)
        for row in report[report.status != "failed"].itertuples():
            with _about(row.output):
                deliver.ship(row.output, args.to, args.mips, args.gpu, args.green)
    failed = report[report.status == "failed"]
    for row in failed.itertuples():
        named = row.error.startswith(f"{row.input}:")
        print(f"bandelets: failed: {row.error if named else f'{row.input}: {row.error}'}", file=sys.stderr)
    counts = report.status.value_counts()
    print(", ".join(f"{counts.get(s, 0)} {s}" for s in ("ok", "skipped", "failed")))
    return 1 if len(failed) else 0


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = _build_parser()
    commands = {"encode": _encode, "decode": _decode, "info": _info, "demo": _demo, "rd": _rd, "show": _show}
    commands |= {"mesh-encode": _mesh_encode, "mesh-decode": _mesh_decode, "geometry-image": _geometry_image}
    commands["batch"] = _batch
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            args = parser.parse_args(argv)
            if commands[args.command](args):  # batch: some inputs failed
                return 1
        except _UsageError as err:
            print(f"bandelets: error: {err} (see bandelets --help)", file=sys.stderr)
            return 2
        except (ValueError, OSError) as err:
            print(f"bandelets: error: {err}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("bandelets: interrupted", file=sys.stderr)
            return 130
        finally:
            ours = Path(__file__).resolve().parent
            for w in caught:  # only ours: a library's notice (numba's threading layer) is not news
                if Path(w.filename).resolve().is_relative_to(ours):
                    print(f"bandelets: warning: {w.message}", file=sys.stderr)
    return 0
