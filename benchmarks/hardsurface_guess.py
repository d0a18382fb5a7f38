"""The default effort's guess of the hard-surface variant (issue 37) on windows of the shared maps.

    python benchmarks/hardsurface_guess.py                 # every window below
    python benchmarks/hardsurface_guess.py vent boombox    # the windows whose name holds a word

(from the repository root.) :mod:`bandelets.codec.hardsurface` guesses from a map's runs of equal
samples whether effort 9's variant (Haar along the bandelet directions, the directions forced:
:data:`bandelets.codec.variants.VARIANTS`) codes it better than the defaults. Its bounds were set on
the maps of ``benchmarks/vs_avif.py``; this checks the guess on other windows of the shared real
maps (read as ``vs_avif.py`` reads them): the vent decal's four quarters and the vent turned a
quarter (x and y swapped with the axes), four 512 x 512 windows of the boombox, the cobblestones'
bottom-right quarter and a quarter of the leather cap. For each: the run fractions along the rows
and the columns, the guess, and the BD-PSNR of the variant over the defaults (the guess patched
off) at 0.25, 0.35, 0.5 and 1 bpp, every point measured from its file.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import bandelets
from bandelets.codec import hardsurface
from bandelets.codec.variants import VARIANTS
from bandelets.metrics import bits_per_pixel, psnr
from bandelets.transform.normals import unit_vectors

sys.path.insert(0, str(Path(__file__).resolve().parent))
from vs_avif import bd, maps  # noqa: E402

RATES = (0.25, 0.35, 0.5, 1.0)
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


def curve(vectors: np.ndarray, options: dict) -> list[tuple[float, float]]:
    """The finite points of ``vectors`` coded at :data:`RATES` with ``options``."""
    points = []
    for rate in RATES:
        data = bandelets.encode(vectors, bpp=rate, kind="normal-map", depth=8, **options)
        quality = psnr(unit_vectors(vectors), bandelets.decode(data), "normal-map")
        if np.isfinite(quality):
            points.append((bits_per_pixel(len(data), vectors.shape), quality))
    return points


def main(words: list[str]) -> None:
    guess = hardsurface.wants_haar_along_directions
    hardsurface.wants_haar_along_directions = lambda array: False  # the defaults without the guess
    for name, vectors in windows():
        if words and not any(w in name for w in words):
            continue
        rows, columns = hardsurface.run_fractions(vectors)
        gain = bd(curve(vectors, VARIANTS[1]), curve(vectors, {}))
        print(
            f"{name}: runs {rows:.3f} / {columns:.3f}, guessed {guess(vectors)}; "
            f"the variant over the defaults {gain:+.2f} dB",
            flush=True,
        )


if __name__ == "__main__":
    main(sys.argv[1:])
