"""The lifting's choice on a large map, made on the whole image and on the mosaic of
:mod:`bandelets.search.sampled` (issue 36): the levels lifted, whether the pair codes were chosen, the
cost ratio of the lifted coefficients over the plain ones (:func:`bandelets.search.directions.cost_ratio`,
which :func:`bandelets.search.directions.pays` compares with ``PAYS_BELOW``) and the process CPU time of
each, at a few thresholds, for mosaics of a quarter and an eighth of the image.

    python benchmarks/sampled_lifting.py [--map boombox_2048] [--thresholds 0.006,0.016,0.04]

The map is read as ``benchmarks/rd_normal_maps.py`` reads it and planned as the encoder plans it
(:func:`bandelets.codec.plan.plan_image`, all its wavelet levels; 0.016 is the threshold of the
boombox's 1 bpp file).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from bandelets.codec.options import EncodeOptions
from bandelets.codec.plan import plan_image
from bandelets.search import directions, sampled
from bandelets.transform.bandelets import padded_channels
from bandelets.transform.directional import LEVELS, SLOPES_97

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_normal_maps import load  # noqa: E402


def _decided(channels: list[np.ndarray], levels: int, threshold: float) -> str:
    """The choice of :func:`bandelets.search.directions.lift` on ``channels``, its ratio and CPU time."""
    start = time.process_time()
    coefficients, fields, lifted, cost = directions.lift(channels, levels, LEVELS, threshold)
    ratio = directions.cost_ratio(channels, coefficients, fields, levels, lifted, threshold, None, cost)
    pairs = any(np.any(f >= len(SLOPES_97)) for f in fields)
    return f"{lifted} levels, pairs {pairs}, ratio {ratio:.4f} ({time.process_time() - start:.1f} s)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--map", default="boombox_2048")
    parser.add_argument("--maps", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--thresholds", default="0.006,0.016,0.04")
    args = parser.parse_args()
    plan, _, coded = plan_image(
        load(args.maps / f"{args.map}.png"), EncodeOptions(kind="normal-map", depth=8)
    )
    channels = padded_channels(coded, plan.levels)
    print(f"{args.map}: {plan.channels} channels, {plan.levels} levels")
    for t in (float(v) for v in args.thresholds.split(",")):
        print(f"T={t:g}: whole image {_decided(channels, plan.levels, t)}")
        for share in (0.25, 0.125):
            sample = sampled.mosaic(channels, plan.levels, share)
            print(f"    mosaic of {share:g} {sample[0].shape}: {_decided(sample, plan.levels, t)}")


if __name__ == "__main__":
    main()
