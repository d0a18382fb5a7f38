"""Command line: argument parsing and error reporting only.

Every command imports the codec (numba, imagecodecs) when it runs, so that
``bandelets --help`` starts at once; the choices come from :mod:`bandelets.format.header`, which
imports nothing. Any error the user can cause ends in one line
``bandelets: error: ...`` on stderr and exit status 2; outputs are written to a temporary
file and renamed, so a failed command leaves nothing behind.
"""

from __future__ import annotations

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
    Kind,
)
from . import deliver
from .arguments import UsageError, build_parser
from .cliopts import rate_list

__all__ = ["main"]

# bandelets.io.files.SUFFIXES and the refused ones: not names for a .bdl file.
IMAGE_SUFFIXES = (".png", ".npy", ".exr", ".tif", ".tiff", ".jpg", ".jpeg", ".webp")


def _working(quiet: bool = False) -> None:
    """Called by each command once its arguments are checked, before the codec loads: from here
    on numba may compile the kernels, and :func:`bandelets.runtime.compilation.announce` says so, unless
    ``-q`` asks for silence, as gzip's does, and compiles the decoder's in a second process
    meanwhile (numba itself takes a third of a second to import: not for an argument error)."""
    from ..runtime.compilation import announce

    announce(quiet=quiet, warm=True)


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
            raise UsageError(f"--{option.replace('_', '-')} must be a positive number, got {value:g}")


def _encode(args) -> None:
    _check_targets(args)
    if args.lossless and args.no_lossless:
        raise UsageError("--lossless and --no-lossless contradict each other")
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
        box_mips=args.box_mips,
        tile=args.tile,
        lossless=True if args.lossless else False if args.no_lossless else None,
        effort=args.effort,
    )
    encoded = encode_with_stats(array, options, **target, measured=not args.quiet)
    if args.green == "down":
        if args.kind != "normal-map":
            raise UsageError("--green is for normal maps (--kind normal-map)")
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
        raise UsageError(f"--level is 0 or more, not {args.level}")
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
    from ..surfaces import chartcodec, parts

    if data[:4] in (chartcodec.MAGIC, parts.MAGIC):  # a mesh record: no image header of its own
        from .meshsummary import representation

        with _about(args.input):
            print(json.dumps(representation(data)))
        return
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
        info["representation"] = "spherical geometry image"
    if header.kind == Kind.NORMAL_MAP:
        info |= {"layout": header.layout, "folded": header.folded, "green": header.green}
    if header.kind == Kind.GEOMETRY_IMAGE or header.frames:
        info |= {"frames": header.frames, "normal_weight": header.normal_weight}
    print(json.dumps(info))


def _demo(args) -> None:
    _working()
    from .demo import run_demo

    rates = rate_list(args.rates, "--rates")
    if args.size < 16:
        raise ValueError(f"--size must be at least 16, got {args.size}")
    run_demo(args.size, rates, Path(args.out), progress=sys.stderr.isatty())


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
    rates = rate_list(args.rates or default_rates, "--rates")
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

    start = time.perf_counter()
    with _about(args.input):  # the mesh's checks name what is wrong, not which file
        mesh = load_mesh(args.input)
        data = encode_mesh(
            mesh,
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
    from .meshsummary import mesh_encode_summary

    elapsed = time.perf_counter() - start
    print(mesh_encode_summary(args.input, args.output, mesh, data, elapsed), file=sys.stderr)


def _mesh_decode(args) -> None:
    _check_input(args.input)
    _check_output(args.input, args.output, args.force)
    file_type = Path(args.output).suffix.lower().lstrip(".")
    if file_type not in ("obj", "ply", "off"):  # bandelets.surfaces.codec.MESH_FORMATS
        raise ValueError(f"{args.output}: unsupported mesh format; use .obj, .ply or .off")
    if args.vertices is not None and args.vertices < 4:
        raise UsageError(f"--vertices must be at least 4 (a closed mesh), got {args.vertices}")
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
        if _chart_image(args, mesh):
            return
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


def _chart_image(args, mesh) -> bool:
    """The multi-chart image and report of a mesh the spherical path refuses (False if it takes it)."""
    from ..io.files import write_array
    from ..surfaces.chartreport import chart_report
    from ..surfaces.codec import is_genus0

    if is_genus0(mesh):
        return False
    if args.normals:
        raise ValueError("--normals needs a closed genus-0 mesh (a spherical geometry image)")
    r = chart_report(mesh, args.size)
    if args.output:
        write_array(args.output, r["image"], "geometry-image", 0)
    if args.report:
        print(
            f"{args.input}: {len(mesh.vertices)} vertices; {r['charts']} charts using "
            f"{100 * r['used']:.1f} % of the {r['side']} x {r['side']} image; "
            f"stretch {r['stretch']:.3f} (1 at best); seam copies "
            f"{100 * r['seam_copies']:.1f} % of the vertices; uncoded: Hausdorff PSNR {r['psnr']:.2f} dB"
        )
    return True


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
    parser = build_parser()
    commands = {"encode": _encode, "decode": _decode, "info": _info, "demo": _demo, "rd": _rd, "show": _show}
    commands |= {"mesh-encode": _mesh_encode, "mesh-decode": _mesh_decode, "geometry-image": _geometry_image}
    commands["batch"] = _batch
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            args = parser.parse_args(argv)
            if commands[args.command](args):  # batch: some inputs failed
                return 1
        except UsageError as err:
            print(f"bandelets: error: {err} (see bandelets --help)", file=sys.stderr)
            return 2
        except (ValueError, OSError) as err:
            print(f"bandelets: error: {err}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("bandelets: interrupted", file=sys.stderr)
            return 130
        finally:
            ours = Path(__file__).resolve().parents[1]  # the package, not only apps/
            for w in caught:  # only ours: a library's notice (numba's threading layer) is not news
                if Path(w.filename).resolve().is_relative_to(ours):
                    print(f"bandelets: warning: {w.message}", file=sys.stderr)
    return 0
