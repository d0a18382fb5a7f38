"""Bytes of the coarse approximation under format version 18's model and version 17's, the same bins.

    python benchmarks/approximation_bytes.py                      # the maps of rd_defaults.py
    python benchmarks/approximation_bytes.py --maps fandisk-top@256 --rates 0.25 0.5

(from the repository root; about a minute.) Each map of ``benchmarks/rd_defaults.py`` is encoded
with the defaults at each rate; the bins of its file are coded again (``bandelets.coding.image.code_image``),
with the approximation in its own contexts (:mod:`bandelets.coding.approximation`, what the file holds)
and as version 17 coded it (``estimate=True``: the detail coefficients' class 0). Prints the ideal
code length of the approximation under both, in bytes, its share of the coefficient stream, and
what the whole stream saves, as a share of the file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import bandelets
from bandelets.codec.decoder import decoded_bins
from bandelets.coding.image import code_image, new_coders
from bandelets.format.header import unpack

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_defaults import MAPS, _maps  # noqa: E402


def _spent(header, trees, bins, estimate: bool) -> tuple[float, float]:
    """Bytes of the approximation and of the whole coefficient stream (ideal code lengths)."""
    _, _, spent = code_image(new_coders(), header, trees, [b.ravel().copy() for b in bins], estimate=estimate)
    h, w = bins[0].shape[0] >> header.levels, bins[0].shape[1] >> header.levels
    approximation = sum(float(s.reshape(bins[0].shape)[:h, :w].sum()) for s in spent) / 8
    return approximation, sum(float(s.sum()) for s in spent) / 8


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--maps", nargs="+", default=list(MAPS))
    parser.add_argument("--rates", nargs="+", type=float, default=[0.25, 0.5, 1.0, 2.0])
    parser.add_argument("--real", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--meshes", type=Path, default=Path("../shared/data/meshes"))
    args = parser.parse_args()
    print("map, bpp, levels: approximation bytes (version 18 / 17), its share, the stream's saving")
    for name, (vectors, depth) in _maps(args.maps, args.real, args.meshes):
        for rate in args.rates:
            data = bandelets.encode(vectors, bpp=rate, kind="normal-map", depth=depth)
            header, streams = unpack(data)[:2]
            if header.transform == "lossless":
                continue
            trees, bins, _ = decoded_bins(header, streams)
            ours, total = _spent(header, trees, bins, False)
            before, total_before = _spent(header, trees, bins, True)
            print(
                f"{name} {rate:g} {header.levels}: {ours:.0f} / {before:.0f} "
                f"({100 * ours / total:.0f} % of {total:.0f}), "
                f"{100 * (total_before - total) / len(data):+.2f} % of {len(data)}"
            )


if __name__ == "__main__":
    main()
