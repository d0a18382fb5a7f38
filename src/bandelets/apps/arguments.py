"""The command line's arguments: one parser per command, their numbers parsed with their bounds
(:mod:`bandelets.apps.cliopts`). Nothing here loads the codec: ``bandelets --help`` starts at once.
"""

from __future__ import annotations

import argparse

from ..format.fields import (
    DEFAULT_NORMAL_WEIGHT,
    DEFAULT_TRANSFORM_1D,
    DEFAULT_WAVELET,
    EXTENSIONS,
    KINDS,
    TRANSFORMS,
    TRANSFORMS_1D,
    WAVELETS,
)
from . import deliver
from .cliopts import effort_level, memory_size, natural_int, positive_float, positive_int

__all__ = ["FORMATS", "UsageError", "build_parser"]

FORMATS = "PNG (8/16-bit), TIFF (8/16-bit, float), OpenEXR (.exr) or .npy"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, like every other error
        raise UsageError(message)


class UsageError(Exception):
    """An argument error: one line, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="bandelets",
        description="Compress images, normal maps and geometry "
        "images with geometric bandelets (Peyre and Mallat 2005).",
    )
    parser.add_argument("--version", action="version", version="bandelets 0.1.0")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    _add_encode(sub)
    _add_decode(sub)
    _add_info(sub)
    _add_demo(sub)
    _add_rd(sub)
    _add_show(sub)
    _add_mesh_encode(sub)
    _add_mesh_decode(sub)
    _add_geometry_image(sub)
    _add_batch(sub)
    return parser


def _add_encode(sub) -> None:
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
    target.add_argument("--bpp", type=positive_float, help="target rate in bits per pixel (default 1)")
    target.add_argument("--threshold", type=positive_float, help="quantization threshold T")
    target.add_argument(
        "--psnr", type=positive_float, help="target PSNR in dB, of the decoded image at the input's bit depth"
    )
    target.add_argument(
        "--max-angle",
        type=positive_float,
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
        "--box-mips",
        action="store_true",
        help="make every prefix level (decode --level K) the box mip of the coded map, as a GPU mip chain "
        "is made: a box wavelet (rbio1.3 unless haar is given) and a normal map's three channels; costs "
        "rate (docs/gpu.md)",
    )
    p.add_argument(
        "--tile",
        type=natural_int,
        default=0,
        metavar="N",
        help="code an image with a side above N pixels in independent tiles of about N x N, two at a time "
        "(bounded memory at any size, a region decodes alone; default: tiles of 512 only for an image "
        "that would not fit --max-memory in one piece)",
    )
    p.add_argument(
        "--effort",
        type=effort_level,
        default=7,
        metavar="N",
        help="how much the encoder tries, 1 (fastest) to 9 (default 7: every search; below 7 the estimates "
        "choose among directions, the Riesz pair and the count of levels without encoding the runners-up, "
        "below 5 no bandelet geometry but on hard-surface maps, about half the time; below 3 no loop "
        "filter either; 9: a normal map also coded with Haar along forced directions, the better "
        "file kept, for hard-surface maps, twice the time; below 9 that variant alone where the map's runs "
        "of equal samples lie along one axis only); the file's format is the same",
    )
    deliver.add_green_option(p, decoding=False)
    _common(p)


def _add_decode(sub) -> None:
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


def _add_info(sub) -> None:
    p = sub.add_parser("info", help="print what a .bdl file holds, as one JSON object")
    p.add_argument("input")


def _add_demo(sub) -> None:
    p = sub.add_parser("demo", help="compress a generated normal map with bandelets and wavelets")
    p.add_argument("--size", type=positive_int, default=512, help="side of the generated map (default 512)")
    p.add_argument("--rates", default="0.25,0.5,1,2", help="target bpp list (default 0.25,0.5,1,2)")
    p.add_argument("--out", default="bandelets-demo", help="folder for the files (default bandelets-demo)")


def _add_rd(sub) -> None:
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
        type=positive_int,
        help="side of the geometry image of meshes (default: chosen for each rate, as mesh-encode does)",
    )
    p.add_argument("--out", default="rd", help="folder for the files, rd.csv and rd.png (default rd)")
    p.add_argument("--decay", action="store_true", help="also fit the decay exponent of log MSE vs log bits")


def _add_show(sub) -> None:
    p = sub.add_parser("show", help="draw the quadtrees and directions of a .bdl file (paper figure 6)")
    p.add_argument("input")
    p.add_argument("output", help="the PNG to write")
    p.add_argument("-f", "--force", action="store_true", help="overwrite an existing output")


def _add_mesh_encode(sub) -> None:
    p = sub.add_parser(
        "mesh-encode",
        help="compress a triangle mesh: a closed genus-0 one as a spherical geometry image, any other "
        "(open, any genus, several parts) as a multi-chart geometry image with its faces",
    )
    p.add_argument("input", help="triangle mesh (OBJ, PLY, OFF, STL, ...)")
    p.add_argument("output", help="the .bdl file to write")
    p.add_argument(
        "--size",
        type=positive_int,
        help="side of the geometry image, even (default: the largest of 64, 128, 256, 512, 1024 that "
        "gets at least 0.1 bit per pixel of a --bits-per-vertex or --bytes target; 256 with --bpp)",
    )
    target = p.add_mutually_exclusive_group()
    target.add_argument("--bpp", type=positive_float, help="bits per geometry-image pixel (default 1)")
    target.add_argument("--bits-per-vertex", type=positive_float, help="bits per vertex of the input mesh")
    target.add_argument("--bytes", type=positive_int, help="size of the whole file")
    p.add_argument("--transform", choices=TRANSFORMS, default="bandelet")
    p.add_argument(
        "--no-frames", action="store_true", help="code the positions as they are, not in local frames"
    )
    p.add_argument(
        "--normal-weight",
        type=positive_float,
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


def _add_mesh_decode(sub) -> None:
    p = sub.add_parser("mesh-decode", help="rebuild the mesh of a mesh .bdl file")
    p.add_argument("input")
    p.add_argument("output", help=".obj, .ply or .off")
    size = p.add_mutually_exclusive_group()
    size.add_argument(
        "--vertices",
        type=positive_int,
        metavar="N",
        help="simplify the mesh to N vertices (default: the original mesh's count, stored in the file; "
        "a multi-chart file always has the original's faces)",
    )
    size.add_argument(
        "--full", action="store_true", help="write the whole grid: one vertex per geometry-image pixel"
    )
    p.add_argument("-f", "--force", action="store_true", help="overwrite an existing output")


def _add_geometry_image(sub) -> None:
    p = sub.add_parser(
        "geometry-image",
        help="spherical geometry image (and normal map) of a closed genus-0 mesh; the multi-chart image "
        "of any other",
    )
    p.add_argument("input", help="triangle mesh (OBJ, PLY, OFF, STL, ...)")
    p.add_argument("output", nargs="?", help="the .npy to write (n x n x 3 float32 positions)")
    p.add_argument("--size", type=positive_int, default=256, help="side of the image, even (default 256)")
    p.add_argument(
        "--report",
        action="store_true",
        help="print the parameterization's stretch, sample area ratio, and the uncoded image's "
        "Hausdorff PSNR and area against the original",
    )
    p.add_argument("--normals", help="also write the unit normals: 16-bit .png or float32 .npy")
    p.add_argument("-f", "--force", action="store_true", help="overwrite existing outputs")


def _add_batch(sub) -> None:
    p = sub.add_parser("batch", help="compress folders of images and meshes on Dask (local or a cluster)")
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="files, folders (recursive) and globs")
    p.add_argument("--out", required=True, metavar="DIR", help="folder of the .bdl files and the report")
    target = p.add_mutually_exclusive_group()
    target.add_argument(
        "--bpp", type=positive_float, help="target rate of the images (default 1), or of meshes"
    )
    target.add_argument("--psnr", type=positive_float, help="target PSNR of the images in dB")
    target.add_argument("--threshold", type=positive_float, help="quantization threshold T of the images")
    p.add_argument("--kind", choices=KINDS, default="image", help="kind of the image inputs (default image)")
    p.add_argument("--bits-per-vertex", type=positive_float, metavar="V", help="target of the meshes")
    p.add_argument(
        "--workers", type=positive_int, metavar="N", help="local worker processes (default one per core)"
    )
    p.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, tcp://HOST:PORT")
    p.add_argument("--report", metavar="FILE", help="report .csv or .parquet (default DIR/report.csv)")
    p.add_argument("-f", "--force", action="store_true", help="redo files an earlier run left up to date")
    deliver.add_batch_options(p)


def _common(p: argparse.ArgumentParser) -> None:
    """Options of encode and decode besides their own."""
    p.add_argument(
        "--max-memory",
        type=memory_size,
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
