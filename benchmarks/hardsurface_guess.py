"""The default effort's guess of the hard-surface variant (issue 37) on windows of the shared maps.

    python benchmarks/hardsurface_guess.py                 # every window below
    python benchmarks/hardsurface_guess.py vent boombox    # the windows whose name holds a word

(from the repository root.) :mod:`bandelets.codec.hardsurface` guesses from a map's runs of equal
samples whether effort 9's variant (Haar along the bandelet directions, the directions forced:
:data:`bandelets.codec.variants.VARIANTS`) codes it better than the defaults. Its bounds were set on
the maps of ``benchmarks/vs_avif.py``; this checks the guess on other windows of the shared real
maps (read as ``vs_avif.py`` reads them): the vent decal's four quarters and the vent turned a
quarter (x and y swapped with the axes), four 512 x 512 windows of the boombox, the cobblestones'
bottom-right quarter and a quarter of the leather cap; and two generated 512 x 512 maps of 8-bit
samples made of one-axis structure (:func:`louvres`, :func:`strips`). For each: the run fractions
along the rows and the columns, the guess, and the BD-PSNR of the variant over the defaults (the
guess patched off) at 0.25, 0.35, 0.5 and 1 bpp (the generated maps, which are lossless by 0.2 bpp,
at :data:`LOW_RATES`), every point measured from its file, a lossless file left out.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import bandelets
from bandelets.codec import hardsurface
from bandelets.codec.variants import VARIANTS
from bandelets.format.header import unpack
from bandelets.metrics import bits_per_pixel, psnr
from bandelets.transform.normals import unit_vectors

sys.path.insert(0, str(Path(__file__).resolve().parent))
from vs_avif import bd, maps  # noqa: E402

RATES = (0.25, 0.35, 0.5, 1.0)
LOW_RATES = (0.05, 0.08, 0.12, 0.2, 0.3)
REAL = Path("../shared/data/normal-maps")
SOURCES = (
    "godot_scifi_vent_decal_512",
    "boombox_2048",
    "learnwgpu_cobblestone_1024",
    "flighthelmet_leather_512",
)


def windows():
    """``name -> vectors`` of the windows of the module docstring whose source is present."""
    got = dict(maps(list(SOURCES), REAL))
    if (vent := got.get(SOURCES[0])) is not None:
        for row in (0, 256):
            for col in (0, 256):
                yield f"vent[{row}:{row + 256},{col}:{col + 256}]", vent[row : row + 256, col : col + 256]
        yield "vent turned", np.transpose(vent, (1, 0, 2))[..., [1, 0, 2]]
    if (boombox := got.get(SOURCES[1])) is not None:
        for row, col in ((0, 0), (1536, 1536), (512, 0), (1024, 1536)):
            yield f"boombox[{row}:{row + 512},{col}:{col + 512}]", boombox[row : row + 512, col : col + 512]
    if (stones := got.get(SOURCES[2])) is not None:
        yield "cobblestone[512:,512:]", stones[512:, 512:]
    if (leather := got.get(SOURCES[3])) is not None:
        yield "leather[256:,:256]", leather[256:, :256]
    yield "louvres (generated)", louvres()
    yield "strips (generated)", strips()


def _from_heights(heights: np.ndarray) -> np.ndarray:
    """The unit normals of a height field, as read from 8-bit samples."""
    dy, dx = np.gradient(heights)
    normals = np.stack([-dx, -dy, np.ones_like(heights)], -1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    return np.rint((normals + 1.0) / 2.0 * 255.0) / 255.0 * 2.0 - 1.0


def louvres(size: int = 512) -> np.ndarray:
    """Chevron slats: a ramp profile repeating every 32 rows, bent by 45 degrees off the middle."""
    rows, columns = np.mgrid[0:size, 0:size].astype(np.float64)
    bent = (rows + 0.5 * np.clip(np.abs(columns - size / 2) - size / 5, 0.0, None)) % 32
    return _from_heights(np.where(bent < 20, np.minimum(bent, 20 - bent) * 0.6, 0.0))


def strips(size: int = 512, seed: int = 3) -> np.ndarray:
    """A trim sheet: horizontal bevelled strips of random widths and heights, six inset slots."""
    rng = np.random.default_rng(seed)
    profile, row = np.zeros(size), 0
    while row < size:
        width, bevel, top = rng.integers(12, 60), rng.integers(2, 6), rng.uniform(2, 8)
        ramp = np.minimum(np.minimum(np.arange(width), width - 1 - np.arange(width)) / bevel, 1.0) * top
        profile[row : row + width] = ramp[: size - row]
        row += width + rng.integers(2, 8)
    heights = np.repeat(profile[:, None], size, 1)
    for _ in range(6):
        top, left = rng.integers(0, size - 40, 2)
        heights[top : top + 30, left : left + 8] -= 3.0
    return _from_heights(heights)


def curve(vectors: np.ndarray, options: dict, rates=RATES) -> list[tuple[float, float]]:
    """The points of ``vectors`` coded at ``rates`` with ``options``, lossless files left out."""
    points = []
    for rate in rates:
        data = bandelets.encode(vectors, bpp=rate, kind="normal-map", depth=8, **options)
        if unpack(data)[0].transform != "lossless":
            quality = psnr(unit_vectors(vectors), bandelets.decode(data), "normal-map")
            points.append((bits_per_pixel(len(data), vectors.shape), quality))
    return points


def main(words: list[str]) -> None:
    guess = hardsurface.wants_haar_along_directions
    hardsurface.wants_haar_along_directions = lambda array: False  # the defaults without the guess
    for name, vectors in windows():
        if words and not any(w in name for w in words):
            continue
        rows, columns = hardsurface.run_fractions(vectors)
        rates = LOW_RATES if "generated" in name else RATES
        gain = bd(curve(vectors, VARIANTS[1], rates), curve(vectors, {}, rates))
        print(
            f"{name}: runs {rows:.3f} / {columns:.3f}, guessed {guess(vectors)}; "
            f"the variant over the defaults {gain:+.2f} dB",
            flush=True,
        )


if __name__ == "__main__":
    main(sys.argv[1:])
