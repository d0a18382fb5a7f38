"""BD-PSNR of bandelets over AVIF at its strongest on the normal maps of issue 37.

    python benchmarks/vs_avif.py --save-avif out/vs-avif-avif.json            # first run: codes AVIF
    python benchmarks/vs_avif.py --avif out/vs-avif-avif.json --save out/vs-avif-main.json
    python benchmarks/vs_avif.py --avif out/vs-avif-avif.json --against out/vs-avif-main.json \\
        --maps godot_scifi_vent_decal_512 bevel@512 --option effort=9

(from the repository root.) The maps (``--maps``; a map whose file is absent is skipped with a
message): the shared real maps of ``../shared/data/normal-maps`` by their name without ``.png``
(read as ``benchmarks/rd_normal_maps.py`` reads them: 8-bit samples, the Z of the XY acacia door
rebuilt), a 512 x 512 crop of one by ``NAME:512`` (the window of :data:`CROPS`, else the top left),
and the generated ones by ``NAME@SIZE`` (:mod:`bandelets.samples`; ``bevel`` is 8-bit samples).
The default list is the 512-or-smaller set of the issue (:data:`MAPS`); the full boombox
(``boombox_2048``) and cobblestones (``learnwgpu_cobblestone_1024``) are slow, on request.

For each map and each rate of ``--rates`` (default 0.25 to 2 bpp, five rates), one file per
codec, every bpp ``8 x bytes / pixels`` of the file and every PSNR that of its decoded vectors,
renormalised, against the map's unit vectors (:func:`bandelets.metrics.psnr`, ``normal-map``):

* bandelets: ``bandelets.encode(map, bpp=B, kind="normal-map", depth=8, **options)`` where
  ``--option key=value`` (repeatable) adds a keyword (``effort=9``, ``wavelet=haar``);
* AVIF at its strongest: every setting of :data:`bandelets.apps.anchors.AVIF_SETTINGS` (4:4:4,
  the identity matrix at speed 2 and YCbCr at speed 4) at every rate, as
  :func:`bandelets.apps.anchors.encode` drives it (the largest file not above the target), and at
  each target the better of the two points is AVIF's curve (:func:`envelope`).

Prints each map's points and its BD-PSNR over AVIF (on finite points: a lossless file is left out,
as ``benchmarks/rd_defaults.py`` does), with ``--against`` over an earlier run's bandelets curve
too, the mean over the maps, and the CPU time of the bandelets encodes. AVIF's points take most of
the time: ``--save-avif`` keeps them, ``--avif`` reads them back (for the same maps and rates);
``--ours`` reads bandelets' points back from a ``--save`` (the table of a run again, no encoding).
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
import time
from pathlib import Path

import numpy as np

import bandelets
from bandelets.apps import anchors
from bandelets.format.header import unpack
from bandelets.metrics import bd_psnr, bits_per_pixel, psnr
from bandelets.transform.normals import unit_vectors

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_normal_maps import load, sample  # noqa: E402

#: The maps of issue 37 at 512 x 512 or less (the full 2048 boombox and 1024 cobblestones on request).
MAPS = (
    "godot_scifi_vent_decal_512",
    "bevel@512",
    "flighthelmet_leather_512",
    "boombox_2048:512",
    "learnwgpu_cobblestone_1024:512",
    "acacia_door_bottom_n",
    "lava_flow_n",
)
#: Top-left corner of the crop of a map (else ``(0, 0)``): the boombox's dial and buttons (its
#: busiest 512 window; most of the map is a flat background).
CROPS = {"boombox_2048": (1024, 768)}
RATES = (0.25, 0.35, 0.5, 1.0, 2.0)


def maps(names: list[str], real: Path):
    """``name -> unit vectors`` (from 8-bit samples) of the maps ``names`` whose source is present."""
    for name in names:
        base, _, crop = name.partition(":")
        generated, _, size = base.partition("@")
        if size:
            vectors, _ = sample(generated, int(size))
            yield name, vectors.astype(np.float64)
            continue
        if not (real / f"{base}.png").is_file():
            print(f"skipping {name}: no {real / base}.png", flush=True)
            continue
        pixels = load(real / f"{base}.png")
        if crop:
            row, col = CROPS.get(base, (0, 0))
            pixels = pixels[row : row + int(crop), col : col + int(crop)]
        yield name, pixels.astype(np.float64) / 255.0 * 2.0 - 1.0


def ours(vectors: np.ndarray, rates, options: dict) -> tuple[list[tuple[float, float]], float]:
    """Bandelets' points at ``rates`` (lossless files at infinite PSNR) and the CPU seconds they took."""
    points, seconds = [], 0.0
    for rate in rates:
        start = time.process_time()
        data = bandelets.encode(vectors, bpp=rate, kind="normal-map", depth=8, **options)
        seconds += time.process_time() - start
        decoded = bandelets.decode(data)
        if unpack(data)[0].transform == "lossless":
            if not np.array_equal(decoded, vectors):
                raise RuntimeError("a lossless .bdl file does not decode to its source")
            points.append((bits_per_pixel(len(data), vectors.shape), float("inf")))
            continue
        quality = psnr(unit_vectors(vectors), decoded, "normal-map")
        points.append((bits_per_pixel(len(data), vectors.shape), quality))
    return points, seconds


def avif(vectors: np.ndarray, rates) -> list[tuple[float, float]]:
    """AVIF's points at ``rates`` with every setting of :data:`~bandelets.apps.anchors.AVIF_SETTINGS`."""
    points = []
    for setting in anchors.AVIF_SETTINGS:
        for rate in rates:
            data = anchors.encode(vectors, rate, "avif", "normal-map", 8, avif=setting)
            decoded = anchors.decode(data, "avif", vectors, "normal-map", 8)
            points.append(
                (bits_per_pixel(len(data), vectors.shape), psnr(unit_vectors(vectors), decoded, "normal-map"))
            )
    return points


def envelope(points) -> list[tuple[float, float]]:
    """AVIF at its strongest: at each rate target, the better (higher PSNR) of the settings' points.

    ``points`` holds the points of each setting of :data:`~bandelets.apps.anchors.AVIF_SETTINGS` in
    turn, at the same targets (as :func:`avif` makes them). One point per target keeps the cubic fit
    of the BD-PSNR on a curve of distinct rates (the points of two settings a few bytes apart
    would make it swing).
    """
    settings = len(anchors.AVIF_SETTINGS)
    count = len(points) // settings
    per_target = zip(*(points[k * count : (k + 1) * count] for k in range(settings)), strict=True)
    return [max(candidates, key=lambda p: p[1]) for candidates in per_target]


def bd(a, b) -> float:
    """BD-PSNR of curve ``a`` over curve ``b`` on their finite points."""
    fa, fb = ([p for p in c if np.isfinite(p[1])] for c in (a, b))
    return bd_psnr(*zip(*fa, strict=True), *zip(*fb, strict=True))


def option(text: str) -> tuple[str, object]:
    """``key=value`` as a keyword of :func:`bandelets.encode` (the value a Python literal, or a string)."""
    key, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"{text!r} is not key=value")
    try:
        return key, ast.literal_eval(value)
    except (ValueError, SyntaxError):
        return key, value


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--maps", nargs="+", default=list(MAPS), help=f"maps (default: {' '.join(MAPS)})")
    parser.add_argument("--rates", nargs="+", type=float, default=list(RATES))
    parser.add_argument("--real", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--option", type=option, action="append", default=[], help="encode keyword k=v")
    parser.add_argument("--avif", type=Path, help="AVIF's points from an earlier --save-avif")
    parser.add_argument("--save-avif", type=Path, help="write AVIF's points here (JSON)")
    parser.add_argument("--save", type=Path, help="write bandelets' points here (JSON)")
    parser.add_argument("--against", type=Path, help="bandelets' points of an earlier --save")
    parser.add_argument("--ours", type=Path, help="bandelets' points from an earlier --save (no encoding)")
    args = parser.parse_args(argv)
    options = dict(args.option)
    kept = json.loads(args.avif.read_text()) if args.avif else {}
    earlier = json.loads(args.against.read_text()) if args.against else {}
    saved = json.loads(args.ours.read_text()) if args.ours else {}
    theirs_all, ours_all, gains, total = {}, {}, [], 0.0
    for name, vectors in maps(args.maps, args.real):
        theirs = [tuple(p) for p in kept[name]] if name in kept else avif(vectors, args.rates)
        mine, seconds = (
            ([tuple(p) for p in saved[name]], 0.0) if name in saved else ours(vectors, args.rates, options)
        )
        theirs_all[name], ours_all[name], total = theirs, mine, total + seconds
        gains.append(bd(mine, envelope(theirs)))
        points = " ".join(f"{q:.2f} ({r:.3f})" for r, q in mine)
        line = f"{name}: {points}; over AVIF {gains[-1]:+.2f} dB; encode {seconds:.1f} s CPU"
        if name in earlier:
            line += f"; over the earlier run {bd(mine, earlier[name]):+.3f} dB"
        print(line, flush=True)
        hull = " ".join(f"{q:.2f} ({r:.3f})" for r, q in envelope(theirs))
        print(f"    AVIF's envelope: {hull}", flush=True)
        for path, curves in ((args.save_avif, theirs_all), (args.save, ours_all)):
            if path:  # after every map, so that an interrupted run keeps what it made
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(json.dumps(curves))
    if gains:
        print(f"mean over AVIF {np.mean(gains):+.2f} dB on {len(gains)} maps; encode {total:.1f} s CPU")


if __name__ == "__main__":
    main()
