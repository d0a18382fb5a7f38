"""Where the error and the bits of a normal map's .bdl files go, against AVIF's files at the same
targets: by region (facets, creases, the image's border) and by channel and wavelet level.

    python benchmarks/normal_map_regions.py out/rd-benchmark/mesh-normals/fandisk-normals \\
        out/rd-benchmark/inputs/fandisk-normals.npy

(from the repository root, after ``python benchmarks/rd_surfaces.py --only mesh-normals``, which
writes both; a few seconds.) RUN is a folder of ``bandelets rd`` holding ``bandelet-Bbpp.bdl`` and
``avif-Bbpp.avif`` for each target B; MAP the source (.npy or PNG, as ``bandelets rd`` read it).
Both files of each target are decoded and their squared errors summed in three regions: the
border (within 8 pixels of the image's edge: on a spherical geometry image, its seams), the creases
(within a pixel of a second difference above 0.02) and the facets (the rest). Printed: the ratio
of our error to AVIF's in each region and the share of our error there; then what the coefficient
stream spends on each coded channel (in local frames: the normal component, then the two
tangents), in all and per wavelet level (bytes / nonzero bins), as the entropy coder prices them.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy import ndimage

import bandelets
from bandelets.apps import anchors
from bandelets.codec.decoder import decoded_bins
from bandelets.coding.image import code_image, new_coders
from bandelets.format.header import unpack
from bandelets.io.files import read_array
from bandelets.metrics import psnr
from bandelets.transform.normals import unit_vectors
from bandelets.transform.wavelets import subband_slices

BORDER = 8


def regions(x: np.ndarray) -> dict[str, np.ndarray]:
    """Masks of the border, the creases and the facets of the unit vectors ``x`` (H, W, 3)."""
    second = np.max([np.abs(ndimage.laplace(x[..., c], mode="nearest")) for c in range(3)], axis=0)
    crease = ndimage.binary_dilation(second > 0.02)
    border = np.ones(x.shape[:2], bool)
    border[BORDER:-BORDER, BORDER:-BORDER] = False
    return {"border": border, "creases": crease & ~border, "facets": ~crease & ~border}


def spent(data: bytes) -> str:
    """Bytes of the coefficient stream per channel and level (bytes / nonzero bins)."""
    header, streams = unpack(data)
    trees, bins, _ = decoded_bins(header, streams)
    _, _, bits = code_image(new_coders(), header, trees, [q.ravel() for q in bins])
    total = sum(b.sum() for b in bits)
    lines = []
    for channel, (b, q) in enumerate(zip(bits, bins, strict=True)):
        b = b.reshape(q.shape)
        levels = []
        for level in range(header.levels, 0, -1):
            where = [s for lv, _, s in subband_slices(q.shape, header.levels) if lv == level]
            size, nonzero = sum(b[s].sum() for s in where) / 8, sum(np.count_nonzero(q[s]) for s in where)
            levels.append(f"L{level} {size:.0f}/{nonzero}")
        lines.append(
            f"  channel {channel}: {b.sum() / 8:.0f} B ({100 * b.sum() / total:.0f} %), " + " ".join(levels)
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("run", type=Path, help="folder of bandelet-Bbpp.bdl and avif-Bbpp.avif files")
    parser.add_argument("map", help="the source map (.npy or PNG)")
    args = parser.parse_args()
    source, depth = read_array(args.map, "normal-map")
    x = unit_vectors(np.asarray(source, np.float64))
    masks = regions(x)
    print(", ".join(f"{name} {100 * m.mean():.1f} % of the pixels" for name, m in masks.items()))
    for path in sorted(args.run.glob("bandelet-*bpp.bdl"), key=lambda p: float(p.name[9:-7])):
        target = path.name[9:-7]
        data = path.read_bytes()
        ours = bandelets.decode(data)
        theirs = anchors.decode(
            (args.run / f"avif-{target}bpp.avif").read_bytes(), "avif", source, "normal-map", depth
        )
        e_ours, e_avif = (np.sum((d - x) ** 2, axis=-1) for d in (ours, theirs))
        split = ", ".join(
            f"{name} {e_ours[m].sum() / e_avif[m].sum():.2f} ({100 * e_ours[m].sum() / e_ours.sum():.0f} %)"
            for name, m in masks.items()
        )
        print(
            f"{target} bpp: PSNR {psnr(x, ours, 'normal-map'):.2f} / AVIF"
            f" {psnr(x, theirs, 'normal-map'):.2f} dB;"
            f" error ours / AVIF (share of ours): {split}"
        )
        print(spent(data))


if __name__ == "__main__":
    main()
