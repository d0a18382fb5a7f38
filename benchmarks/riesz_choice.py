"""How the encoder's choice of the Riesz pair (:mod:`bandelets.transform.riesz`) does, map by map and rate
by rate.

    python benchmarks/riesz_choice.py [--maps bevel@256 crease@256 ...] [--rates 0.25,0.5,1,2]

(from the repository root; about 10 minutes for the default maps on the 2-core machine.) The
maps are those of ``benchmarks/rd_defaults.py`` that are coded as two channels (a map whose file
is absent is skipped with a message). For each map: the share of its coded channels' energy that
no height explains (``||g'||^2 / (||g||^2 + ||g'||^2)``, the sign :func:`bandelets.transform.riesz.oriented`
takes), then for each rate the ratio the encoder decides on
(:func:`bandelets.codec.encoder._riesz_pair`: the pair's cost estimate over the channels'), and the
PSNR of the files with the pair forced (``riesz=True``), without it (``riesz=False``) and as the
defaults choose, every file written and decoded (``lossless=False``: the 8-bit maps' lossless
files would answer the high rates). Last, the time of one turn at 512 x 512 (forward, float32
and float64, median of 15) and of the choice's estimate on the 512 x 512 crease map at 1 bpp's
threshold (median of 5). These are the figures of BENCHMARKS, "Where main stands: format
version 15".
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import bandelets
from bandelets import metrics
from bandelets.codec import encoder, normalmaps
from bandelets.codec.options import EncodeOptions
from bandelets.format.header import unpack
from bandelets.samples import crease_normal_map
from bandelets.transform import riesz
from bandelets.transform.bandelets import wavelet_coefficients
from bandelets.transform.wavelets import max_levels

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_defaults import _maps  # noqa: E402

MAPS = (
    "bevel@256",
    "bevel@512",
    "crease@256",
    "crease@512",
    "bumps@256",
    "acacia_door_bottom_n",
    "lava_flow_n",
    "bunny-top@256",
    "fandisk-top@256",
)


def _ratios(vectors, depth, bpp) -> tuple[float, dict]:
    """The ratio the defaults decided on at ``bpp``, and the PSNR of each choice's file."""
    seen = []
    decide = encoder._riesz_pair

    def spy(*args, **kwargs):
        found = decide(*args, **kwargs)
        seen.append(found[3])
        return found

    psnrs = {}
    encoder._riesz_pair = spy
    try:
        for label, choice in (("defaults", None), ("pair", True), ("channels", False)):
            options = {"bpp": bpp, "kind": "normal-map", "depth": depth, "riesz": choice, "lossless": False}
            data = bandelets.encode(vectors, **options)
            quality = metrics.psnr(metrics.unit_vectors(vectors), bandelets.decode(data), "normal-map")
            psnrs[label] = quality, unpack(data)[0].riesz
            if label == "defaults":
                ratio = seen[0] if seen else float("nan")
    finally:
        encoder._riesz_pair = decide
    return ratio, psnrs


def _median(run, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", nargs="+", default=list(MAPS))
    parser.add_argument("--rates", default="0.25,0.5,1,2")
    parser.add_argument("--real", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--meshes", type=Path, default=Path("../shared/data/meshes"))
    args = parser.parse_args()
    rates = [float(r) for r in args.rates.split(",")]
    for name, (vectors, depth) in _maps(args.maps, args.real, args.meshes):
        unit = metrics.unit_vectors(vectors)
        if not normalmaps.faces_one_way(unit):
            print(f"{name}: three channels, no pair")
            continue
        sign, g, curl = riesz.oriented(*np.moveaxis(normalmaps.equidistant(unit), -1, 0))
        share = float(np.sum(curl**2) / (np.sum(g**2) + np.sum(curl**2)))
        print(f"{name}: curl share {100 * share:.2f} % (sign {sign:+d})", flush=True)
        for bpp in rates:
            ratio, psnrs = _ratios(vectors, depth, bpp)
            gain = psnrs["pair"][0] - psnrs["channels"][0]
            print(
                f"  {bpp:g} bpp: ratio {ratio:.3f}, pair {psnrs['pair'][0]:.2f} dB, channels "
                f"{psnrs['channels'][0]:.2f} dB ({gain:+.2f}), defaults {psnrs['defaults'][0]:.2f} dB "
                f"(pair sign {psnrs['defaults'][1]})",
                flush=True,
            )
    rng = np.random.default_rng(0)
    for dtype in (np.float32, np.float64):
        pair = rng.random((2, 512, 512)).astype(dtype)
        seconds = _median(lambda pair=pair: riesz.forward(*pair), 15)
        print(f"one turn, 512 x 512, {np.dtype(dtype).name}: {1e3 * seconds:.1f} ms")
    crease = crease_normal_map(512)
    data = bandelets.encode(crease, bpp=1.0, kind="normal-map")
    threshold, levels = unpack(data)[0].threshold, max_levels((512, 512))
    coded = normalmaps.equidistant(metrics.unit_vectors(crease))
    coefficients = wavelet_coefficients(coded, "cdf97", levels)  # the plain channels, as the encoder has them
    options = EncodeOptions(kind="normal-map")
    estimate = _median(
        lambda: encoder._riesz_pair(coded, coefficients, None, 0, levels, threshold, options, True), 5
    )
    print(f"the choice's estimate, crease map 512 x 512 at T = {threshold:.3g}: {1e3 * estimate:.0f} ms")


if __name__ == "__main__":
    main()
