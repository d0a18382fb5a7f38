"""Rate-distortion on the shared real normal maps: bandelets against AVIF, JPEG XL and OpenJPEG.

    python benchmarks/rd_normal_maps.py [--maps ../shared/data/normal-maps] [--out out/rd-normal-maps]
    python benchmarks/rd_normal_maps.py --samples crease bumps --size 512
    python benchmarks/rd_normal_maps.py --rendered fandisk-top bunny-top --size 512

(from the repository root; about 10 minutes on the 2-core machine.) For every real map of
``--maps`` (skipped with a message when the folder is absent), or with ``--samples`` every
generated map named (:mod:`bandelets.samples`, ``--size`` pixels a side: ``crease`` and ``bumps``
float, the anchors given 16-bit samples, 12-bit for AVIF; ``bevel`` 8-bit samples, as a PNG, given
to every codec as the real maps are), or with ``--rendered`` every object-space map named of
:data:`RENDERED` (:func:`bandelets.surfaces.render.render_normals` of a mesh of ``--meshes``,
16-bit samples, as the held-out maps of issue 15 are, given to every codec: 12-bit to AVIF;
``--background``: the vector of the empty pixels, :data:`BACKGROUNDS`),
and every rate of 0.25 to 2 bpp,
one file per codec, written under ``OUT/MAP/`` and read back; every bpp is ``8 x bytes /
pixels`` of that file and every PSNR that of the vectors it decodes to, renormalised, against
the map's unit vectors (:func:`bandelets.metrics.psnr`, kind ``normal-map``). The codecs:

* ``lifting``: ``bandelets encode --kind normal-map --bpp B``, the defaults (CDF 9/7, bandelets,
  restoration, the two finest levels lifted along directions where they pay, or the two channels
  coded as their Riesz pair where that pays);
* ``unfiltered``: the defaults without the loop filter (``--no-loop-filter``);
* ``bandelet``: the defaults without the directional lifting (``--no-lifting``);
* ``pairless``: the defaults without the Riesz pair (``--no-riesz``: the two channels as they are);
* ``wavelet``: the same coder without any geometry (``--transform wavelet --no-lifting``; the
  Riesz pair where it pays, as in the defaults);
* ``plain``: the same coder without any geometry nor the Riesz pair (``--transform wavelet
  --no-lifting --no-riesz``: the coder of format version 14 without geometry);
* the anchors as :mod:`bandelets.apps.anchors` drives them (8-bit samples, as the PNG): OpenJPEG,
  libavif (4:4:4, identity matrix, speed 2), libjxl (effort 9).

``acacia_door_bottom_n.png`` stores X and Y only (red, green; blue holds ambient occlusion), as
BC5 does: its Z is rebuilt, ``sqrt(1 - x^2 - y^2)``, into an 8-bit RGB map that every codec is
given. The tables (PSNR per point, BD-PSNR of the first codec of ``--codecs``, ``lifting`` by
default, over every other codec, positive: the first better) are printed and stored in
``benchmarks/rd-normal-maps-real.md`` (with ``--samples``,
``benchmarks/rd-normal-maps-samples-SIZE.md``; ``--results PATH`` elsewhere).

Lossless points. The real maps are 8-bit samples: under a rate target that its lossless file
fits, ``bandelets encode`` writes that file (:mod:`bandelets.coding.lossless`), of infinite PSNR, at
its own rate, below the target. The tables print ``lossless (rate)`` for it; a BD-PSNR is
computed on the finite points of both curves only, over the rates both cover (a curve that ends
in a lossless file is cut where it turns lossless: the BD says nothing about the rates above,
where that file beats every finite point). The tables say up to which rate each BD runs. A
second table keeps each curve's first lossless point at the other curve's best finite PSNR: a
lower bound of what the exact file is worth against it, over the whole common range. Then
the lossless rate of every map by each codec at its strongest lossless setting
(:func:`bandelets.apps.anchors.encode_lossless`: ``bandelets encode --lossless``, ``cjxl -d 0 -e 9``,
``avifenc --lossless -s 2``, OpenJPEG reversible, PNG at zlib level 9), each file decoded and
checked to give the samples back.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import imagecodecs
import numpy as np

import bandelets
from bandelets.apps import anchors
from bandelets.format.header import unpack
from bandelets.format.samples import from_samples
from bandelets.io.files import write_atomic
from bandelets.metrics import bd_psnr, bits_per_pixel, psnr
from bandelets.samples import bevel_normal_map, bump_normal_map, crease_normal_map
from bandelets.transform.normals import unit_vectors

HERE = Path(__file__).resolve().parent
RATES = (0.25, 0.35, 0.5, 0.71, 1.0, 1.41, 2.0)
#: Maps whose blue channel is not Z (X and Y only).
XY_MAPS = ("acacia_door_bottom_n.png",)
OURS = {
    "lifting": {},
    "unfiltered": {"loop_filter": False},
    "bandelet": {"lifting": False},
    "pairless": {"riesz": False},
    "wavelet": {"transform": "wavelet", "lifting": False},
    "plain": {"transform": "wavelet", "lifting": False, "riesz": False},
}
CODECS = (*OURS, "jpeg2000", "avif", "jpegxl")
#: Rendered object-space maps: mesh, its axis turned up, crease angle (degrees), view.
RENDERED = {
    "fandisk-top": ("fandisk.off", "-z", 45.0, (0.0, 0.0, 1.0)),
    "fandisk-oblique": ("fandisk.off", "-z", 45.0, (1.0, 1.0, 2.0)),
    "bunny-top": ("bunny.off", "+y", 180.0, (0.0, 0.0, 1.0)),
}
#: Vectors a baker writes where no surface is seen. ``zero`` is 32768 in 16-bit samples, a
#: vector of length 1.5e-5 whose direction any error of one sample turns: the anchors' PSNR
#: collapses on it (AVIF 9 to 21 dB on fandisk-top at 256), so it measures nothing useful.
BACKGROUNDS = {"flat": (0.0, 0.0, 1.0), "black": (-1.0, -1.0, -1.0), "zero": (0.0, 0.0, 0.0)}
SAMPLES = {"crease": crease_normal_map, "bumps": bump_normal_map, "bevel": bevel_normal_map}
#: Codecs of the lossless table.
LOSSLESS = ("bandelets", "jpegxl", "avif", "jpeg2000", "png")


def load(path: Path) -> np.ndarray:
    """The map as 8-bit RGB samples, Z rebuilt for an XY map."""
    pixels = imagecodecs.png_decode(path.read_bytes())[..., :3]
    if path.name in XY_MAPS:
        xy = pixels[..., :2] / 255.0 * 2.0 - 1.0
        z = np.sqrt(np.clip(1.0 - np.sum(xy * xy, axis=-1), 0.0, 1.0))
        pixels = pixels.copy()
        pixels[..., 2] = np.rint((z + 1.0) / 2.0 * 255.0).astype(np.uint8)
    return pixels


def sample(name: str, size: int) -> tuple[np.ndarray, int]:
    """The generated map ``name`` of ``size`` pixels a side and its depth (8 for 8-bit samples, as
    the real maps are given, else 0: float)."""
    array = SAMPLES[name](size)
    return (from_samples(array, "normal-map", 8), 8) if array.dtype == np.uint8 else (array, 0)


def rendered(name: str, size: int, meshes: Path, background: str = "flat") -> tuple[np.ndarray, int] | None:
    """The object-space map ``name`` of :data:`RENDERED`, ``size`` pixels a side, on the
    ``background`` of :data:`BACKGROUNDS`, as its 16-bit samples read back, and 16; None (with
    a message) when the mesh is not in ``meshes``."""
    from bandelets.surfaces.codec import load_mesh
    from bandelets.surfaces.render import render_normals, to_samples, turned_up

    mesh_name, up, crease, view = RENDERED[name]
    if not (meshes / mesh_name).is_file():
        print(f"skipping {name}: {mesh_name} not in {meshes} (see --meshes)")
        return None
    mesh = load_mesh(meshes / mesh_name)
    vertices = turned_up(mesh.vertices, up)
    normals = render_normals(vertices, mesh.faces, size, view, crease, background=BACKGROUNDS[background])
    return from_samples(to_samples(normals, 16), "normal-map", 16), 16


def point(vectors: np.ndarray, depth: int, codec: str, rate: float, folder: Path) -> dict:
    """Encode, write, read back, decode and measure one point (``depth``: of the source, 0 float)."""
    start = time.perf_counter()
    if codec in OURS:
        data = bandelets.encode(vectors, bpp=rate, kind="normal-map", depth=depth, **OURS[codec])
    else:
        data = anchors.encode(vectors, rate, codec, "normal-map", depth)
    encode_s = time.perf_counter() - start
    path = folder / f"{codec}-{rate:g}bpp.{anchors.EXTENSIONS.get(codec, 'bdl')}"
    write_atomic(path, data)
    written = path.read_bytes()
    if codec in OURS:
        decoded = bandelets.decode(written)
    else:
        decoded = anchors.decode(written, codec, vectors, "normal-map", depth)
    quality = psnr(unit_vectors(vectors), decoded, "normal-map")
    # A lossless file decodes to the very values given (renormalising them twice, the reference
    # above, differs in the last bits): its PSNR is infinite.
    if codec in OURS and unpack(written)[0].transform == "lossless":
        if not np.array_equal(decoded, vectors):
            raise RuntimeError("a lossless .bdl file does not decode to its source")
        quality = float("inf")
    return {
        "codec": codec,
        "bpp": bits_per_pixel(len(written), vectors.shape),
        "psnr": quality,
        "encode_s": encode_s,
    }


def _curve(rows: list[dict]) -> tuple[list[float], list[float]]:
    """The finite points of a curve (a lossless file's PSNR is infinite: see the module notes)."""
    finite = [r for r in rows if np.isfinite(r["psnr"])]
    return [r["bpp"] for r in finite], [r["psnr"] for r in finite]


def _bd(ours: tuple, theirs: tuple) -> str:
    """BD-PSNR of ``ours`` over ``theirs`` with the top of the common rate range."""
    top = min(max(ours[0]), max(theirs[0]))
    return f"{bd_psnr(*ours, *theirs):+.2f} (to {top:.2f})"


def _capped(ours: list[dict], theirs: list[dict]) -> str:
    """BD-PSNR of ``ours`` over ``theirs``, the first lossless point of either curve kept at the
    best finite PSNR of the other (a lower bound of what an exact file is worth against it);
    "=" when neither curve has one."""
    curves = [list(ours), list(theirs)]
    for k in (0, 1):
        exact = [r for r in curves[k] if np.isinf(r["psnr"])]
        if exact:
            best = max(r["psnr"] for r in curves[1 - k] if np.isfinite(r["psnr"]))
            curves[k] = [r for r in curves[k] if np.isfinite(r["psnr"])] + [exact[0] | {"psnr": best}]
    if curves == [ours, theirs]:
        return "="
    return f"{bd_psnr(*_curve(curves[0]), *_curve(curves[1])):+.2f}"


def _cell(row: dict) -> str:
    quality = "lossless" if np.isinf(row["psnr"]) else f"{row['psnr']:.2f}"
    return f"{quality} ({row['bpp']:.3f})"


def lossless_rates(samples: np.ndarray) -> dict[str, float]:
    """bpp of the lossless file of 8-bit samples (H, W, 3) by bandelets and each anchor, each
    decoded and checked."""
    pixels = samples.shape[0] * samples.shape[1]
    data = bandelets.encode(samples, kind="normal-map", lossless=True)
    if not np.array_equal(bandelets.decode(data), samples / 255.0 * 2.0 - 1.0):
        raise RuntimeError("a lossless .bdl file does not decode to its source")
    rates = {"bandelets": 8 * len(data) / pixels}
    for codec in ("jpegxl", "avif", "jpeg2000"):
        rates[codec] = 8 * len(anchors.encode_lossless(samples, codec)) / pixels
    rates["png"] = 8 * len(imagecodecs.png_encode(samples, level=9)) / pixels
    return rates


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--maps", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--out", type=Path, default=Path("out/rd-normal-maps"))
    parser.add_argument("--samples", nargs="+", choices=SAMPLES, help="generated maps instead of --maps")
    parser.add_argument("--rendered", nargs="+", choices=RENDERED, help="maps rendered from --meshes instead")
    parser.add_argument("--meshes", type=Path, default=Path("../shared/data/meshes"))
    parser.add_argument("--background", choices=BACKGROUNDS, default="flat", help="of --rendered (flat)")
    parser.add_argument("--size", type=int, default=256, help="side of the generated maps (256)")
    parser.add_argument("--results", type=Path, help="where the tables go (default: see above)")
    parser.add_argument(
        "--codecs",
        default=",".join(CODECS),
        help=f"comma-separated subset of {','.join(CODECS)} (default all)",
    )
    args = parser.parse_args()
    codecs = [c for c in args.codecs.split(",") if c]
    if not codecs or any(c not in CODECS for c in codecs):
        parser.error(f"--codecs: any of {', '.join(CODECS)}")
    reference = codecs[0]  # the BD-PSNRs are those of the first codec over the others
    if args.samples:
        maps = {f"{name}@{args.size}": sample(name, args.size) for name in args.samples}
        results = HERE / f"rd-normal-maps-samples-{args.size}.md"
    elif args.rendered:
        suffix = "" if args.background == "flat" else f"-{args.background}"
        made = {
            f"{name}{suffix}@{args.size}": rendered(name, args.size, args.meshes, args.background)
            for name in args.rendered
        }
        maps = {name: made[name] for name in made if made[name] is not None}
        if not maps:
            return
        results = HERE / f"rd-normal-maps-rendered{suffix}-{args.size}.md"
    else:
        paths = sorted(args.maps.glob("*.png")) if args.maps.is_dir() else []
        if not paths:
            print(f"skipping: no PNG normal maps in {args.maps} (see --maps)")
            return
        maps = {p.stem: (load(p).astype(np.float64) / 255.0 * 2.0 - 1.0, 8) for p in paths}
        results = HERE / "rd-normal-maps-real.md"
        exact = ["| map | " + " | ".join(LOSSLESS) + " |", "|" + " --- |" * (len(LOSSLESS) + 1)]
        for p in paths:
            rates = lossless_rates(load(p))
            exact.append(f"| {p.stem} | " + " | ".join(f"{rates[c]:.3f}" for c in LOSSLESS) + " |")
            print(exact[-1], flush=True)
    lines = ["| map | codec | " + " | ".join(f"{r:g} bpp" for r in RATES) + " |"]
    lines.append("| --- | --- |" + " --- |" * len(RATES))
    gains, capped = [], []
    for name, (vectors, depth) in maps.items():
        folder = args.out / name
        folder.mkdir(parents=True, exist_ok=True)
        curves = {}
        for codec in codecs:
            rows = []
            for rate in RATES:
                try:
                    rows.append(point(vectors, depth, codec, rate, folder))
                except ValueError as err:  # a target below the codec's smallest file
                    print(f"{name}: {codec} at {rate:g} bpp skipped: {err}")
            curves[codec] = rows
            cells = " | ".join(_cell(r) for r in rows)
            lines.append(f"| {name} | {codec} | {cells} |")
            print(lines[-1], flush=True)
        ours = _curve(curves[reference])
        cells = [_bd(ours, _curve(rows)) for codec, rows in curves.items() if codec != reference]
        gains.append(f"| {name} | " + " | ".join(cells) + " |")
        cells = [_capped(curves[reference], rows) for codec, rows in curves.items() if codec != reference]
        capped.append(f"| {name} | " + " | ".join(cells) + " |")
        print(gains[-1], flush=True)
    header = "| map | " + " | ".join(c for c in codecs if c != reference) + " |"
    summary = [header, "|" + " --- |" * len(codecs), *gains]
    text = (
        "PSNR in dB (real bpp in brackets; lossless: the file is exact):\n\n"
        + "\n".join(lines)
        + f"\n\nBD-PSNR of `{reference}` over each codec, dB, from 0.25 bpp to the top of the finite "
        "points both curves have (in brackets, bpp):\n\n" + "\n".join(summary) + "\n"
    )
    text += (
        "\nThe same, each curve's first lossless point kept at the other curve's best finite PSNR "
        "(a lower bound of what the exact file is worth against it; '=': no lossless point, as "
        "above), over the whole common rate range:\n\n" + "\n".join([header, summary[1], *capped]) + "\n"
    )
    if not (args.samples or args.rendered):
        text += "\nLossless files, bpp (each decoded and checked):\n\n" + "\n".join(exact) + "\n"
    command = "python benchmarks/rd_normal_maps.py"
    if args.samples:
        command += f" --samples {' '.join(args.samples)} --size {args.size}"
    if args.rendered:
        command += f" --rendered {' '.join(args.rendered)} --size {args.size}"
        command += "" if args.background == "flat" else f" --background {args.background}"
    if codecs != list(CODECS):
        command += f" --codecs {','.join(codecs)}"
    if args.results:
        results = args.results
        command += f" --results {args.results}"
    results.write_text(f"# `{command}`\n\n{anchors.versions()}\n\n" + text)
    print("\n" + "\n".join(summary))


if __name__ == "__main__":
    main()
