"""How much can bandelets gain on a surface? The geometry-free ceiling, and the real gain.

For each surface, at the threshold ``T`` that the wavelet coder uses at 1 bpp, every detail
subband of every coded channel is cut into squares of width ``L`` and each square is given
the direction that leaves the fewest coefficients at or above ``T`` after the reordering and
the 1D transform (Alpert, two vanishing moments), with no cost for the geometry: an upper
bound on the sparsity bandelets can bring. Printed: the significant coefficients left, in
percent of the wavelet's, for L = 8 and 16; then the real BD-PSNR of bandelets over wavelets
(same coder, CDF 9/7, 0.25 to 2 bpp, real files).

Surfaces: the generated crease normal map at 256 and 512, the 256 map blurred by a Gaussian
of 0.7, 1.5 and 3 pixels (the paper's model: a crease blurred over several samples), the
smooth bumps, and, when ``../shared/data/meshes`` is there, the normal map and the geometry
image (x channel) of fandisk. Then, on the crease map at 256: the ceiling with other 1D
transforms, and inside the squares the real search picks, the significant coefficients and
the bits the real coder spends on them, with and without bandelets.

    python benchmarks/bandelet_ceiling.py [--meshes DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pywt
from scipy import ndimage

import bandelets
from bandelets.codec.encoder import encode_with_stats
from bandelets.codec.options import EncodeOptions
from bandelets.coding.image import code_image, new_coders
from bandelets.coding.order import subband_plan
from bandelets.format.fields import TRANSFORMS_1D
from bandelets.format.header import Header
from bandelets.format.quantizer import quantize
from bandelets.metrics import bd_psnr, bits_per_pixel, psnr
from bandelets.samples import bump_normal_map, crease_normal_map
from bandelets.search.basis import best_trees
from bandelets.transform.bandeletize import bandeletize, transform_rows
from bandelets.transform.bandelets import apply_trees, wavelet_coefficients
from bandelets.transform.geometry import directions
from bandelets.transform.normals import unit_vectors
from bandelets.transform.wavelets import max_levels, subband_slices

RATES = (0.25, 0.5, 1.0, 2.0)


def _along(rows: np.ndarray, transform: str) -> np.ndarray:
    """1D transform of each row: ours (Haar, Alpert) or a PyWavelets orthogonal wavelet."""
    if transform in TRANSFORMS_1D:
        return transform_rows(rows, transform)
    return np.concatenate(pywt.wavedec(rows, transform, mode="periodization", axis=1), axis=1)


def significant_left(
    coefficients: np.ndarray, levels: int, threshold: float, width: int, transform: str = "alpert2"
) -> float:
    """Coefficients at or above ``threshold`` with the best free direction per square, over those
    of the wavelet transform, for every square of ``width`` in every detail subband."""
    orders = directions(width)[1]
    wavelet = bandelet = 0
    for _, _, where in subband_slices(coefficients.shape, levels):
        band = coefficients[where]
        rows, cols = band.shape[0] // width, band.shape[1] // width
        squares = band[: rows * width, : cols * width].reshape(rows, width, cols, width)
        for square in squares.transpose(0, 2, 1, 3).reshape(-1, width * width):
            count = int(np.sum(np.abs(square) >= threshold))
            wavelet += count
            if count < 2:  # nothing to gain
                bandelet += count
                continue
            transformed = _along(square[orders], transform)
            bandelet += min(count, int(np.sum(np.abs(transformed) >= threshold, axis=1).min()))
    return bandelet / max(wavelet, 1)


def bits_per_significant(coefficients: list[np.ndarray], levels: int, threshold: float) -> dict:
    """Inside the squares the search gives a direction at ``threshold``: significant coefficients
    and coded bits (the coder's own ledger) with and without the bandelet transform."""
    trees = best_trees(coefficients, levels, threshold, "bandelet", "alpert2")
    shape = coefficients[0].shape
    inside = np.zeros(shape[0] * shape[1], bool)
    for index, tree in enumerate(trees):
        inside[subband_plan(shape, levels, index, tree, "alpert2")[0].order] = True
    out = {}
    for transform in ("wavelet", "bandelet"):
        header = Header(
            height=shape[0],
            width=shape[1],
            channels=len(coefficients),
            kind="image",
            transform=transform,
            wavelet="cdf97",
            levels=levels,
            threshold=threshold,
        )
        values = coefficients
        if transform == "bandelet":
            values = [apply_trees(c, levels, trees, bandeletize, "alpert2") for c in coefficients]
        q = [quantize(v, threshold).ravel() for v in values]
        _, _, spent = code_image(new_coders(), header, trees if transform == "bandelet" else None, q)
        significant = sum(int(np.count_nonzero(c[inside])) for c in q)
        out[transform] = (significant, sum(float(s[inside].sum()) for s in spent))
    return out


def real_gain(surface: np.ndarray, kind: str) -> float:
    """BD-PSNR (dB) of bandelets over wavelets, same coder, CDF 9/7, real files."""
    curves = {}
    for transform in ("wavelet", "bandelet"):
        points = []
        for rate in RATES:
            data = bandelets.encode(surface, bpp=rate, kind=kind, transform=transform)
            points.append(
                (bits_per_pixel(len(data), surface.shape), psnr(surface, bandelets.decode(data), kind))
            )
        curves[transform] = [[p[0] for p in points], [p[1] for p in points]]
    return bd_psnr(*curves["bandelet"], *curves["wavelet"])


def blurred(normals: np.ndarray, sigma: float) -> np.ndarray:
    channels = [ndimage.gaussian_filter(normals[..., c], sigma, mode="nearest") for c in range(3)]
    return unit_vectors(np.stack(channels, axis=-1))


def surfaces(meshes: Path):
    crease = crease_normal_map(256)
    yield "crease 256", crease, "normal-map"
    yield "crease 512", crease_normal_map(512), "normal-map"
    for sigma in (0.7, 1.5, 3.0):
        yield f"crease 256, blur {sigma} px", blurred(crease, sigma), "normal-map"
    yield "bumps 256", bump_normal_map(256), "normal-map"
    fandisk = meshes / "fandisk.off"
    if not fandisk.exists():
        print(f"(skipping fandisk: {fandisk} not found)")
        return
    from bandelets.surfaces.codec import load_mesh, make_geometry_image

    image = make_geometry_image(load_mesh(fandisk), 256)
    yield "fandisk normals 256", image.normals, "normal-map"
    yield "fandisk geometry x 256", image.positions[..., 0], "image"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=Path(__file__).parents[2] / "shared/data/meshes")
    args = parser.parse_args()
    print(f"{'surface':<26} {'T':>8} {'left L=8':>9} {'L=16':>6} {'real BD-PSNR':>13}")
    for name, surface, kind in surfaces(args.meshes):
        wavelet = encode_with_stats(surface, EncodeOptions(kind=kind, transform="wavelet"), bpp=1.0)
        coded = surface if surface.ndim == 3 else surface[..., None]
        if kind == "normal-map" and np.all(coded[..., 2] >= 0):
            coded = coded[..., :2]  # as the codec does
        levels = max_levels(coded.shape[:2])
        channels = wavelet_coefficients(coded, "cdf97", levels)
        left = [
            np.mean([significant_left(c, levels, wavelet.threshold, width) for c in channels])
            for width in (8, 16)
        ]
        gain = real_gain(surface, kind)
        shares = f"{100 * left[0]:>8.0f}% {100 * left[1]:>5.0f}%"
        print(f"{name:<26} {wavelet.threshold:>8.2g} {shares} {gain:>+12.2f} dB")
        if name == "crease 256":
            crease = (channels, levels, wavelet.threshold)
    channels, levels, threshold = crease
    print(f"\ncrease 256, L = 16, T = {threshold:.2g}: significant coefficients left by 1D transform")
    for transform in (*TRANSFORMS_1D, "db2", "db4", "sym4"):
        share = np.mean([significant_left(c, levels, threshold, 16, transform) for c in channels])
        print(f"  {transform:<8} {100 * share:>4.0f}%")
    counts = bits_per_significant(channels, levels, threshold)
    print("crease 256, inside the squares the search gives a direction:")
    for transform, (significant, bits) in counts.items():
        each = bits / significant
        print(f"  {transform:<8} {significant:>6d} significant, {bits:>8.0f} bits, {each:.2f} per one")


if __name__ == "__main__":
    main()
