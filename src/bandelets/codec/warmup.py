"""The decoder's kernels compiled in a second process while a first run's encoder compiles its own.

A fresh install compiles every numba kernel on its first call, on one core: about 150 s of CPU for
the first encode and decode of a 512 x 512 map. Half of those kernels are the decoder's (the
coefficient and approximation coders, the inverse lifting, the restoration in both precisions, the
loop filter), which the encoder also runs once it has a file. So when the command line hears the
first compilation of a run (:mod:`bandelets.runtime.compilation`), it starts this module as a
process of its own: it decodes the few small files of ``warmup_files/`` (a lifted normal map with its
restoration, one with a loop filter, a Riesz pair, a lossless file), which compiles those kernels
into numba's cache on the other core while the encoder compiles its searches; the encoder then loads
them from the cache instead of compiling them (the first encode of the vent decal map took 92 s of
CPU instead of 150 s on the 2-core machine: BENCHMARKS.md, "The first run").

Numba writes each cache file whole (a temporary file renamed), so two processes compiling at once
never leave a broken kernel; at worst a kernel compiled by both is compiled twice. Numba offers
no such warm-up, and shipping compiled kernels would tie the package to one CPU and one numba.

    python -m bandelets.codec.warmup          # what the first run starts
    python -m bandelets.codec.warmup --make   # the files again, after a change of the format
"""

from __future__ import annotations

import sys
from pathlib import Path

from .decoder import decode

__all__ = ["FILES", "warm_up"]

#: The files decoded, in this order (the coders and the restoration first: the encoder needs them
#: soonest).
FILES = Path(__file__).with_name("warmup_files")
_NAMES = ("lifted", "filtered", "riesz", "lossless")


def warm_up() -> None:
    """Compile the kernels the encoder reaches last (:func:`_late_kernels`), then decode every file of
    :data:`FILES` (with and without the restoration, and at level 1)."""
    _late_kernels()
    for name in _NAMES:
        data = (FILES / f"{name}.bdl").read_bytes()
        decode(data)
        if name != "lossless":
            decode(data, restore=False)
            decode(data, level=1)


def _late_kernels() -> None:
    """The kernels a first encode reaches last, run once on small arrays: the restoration in both
    precisions and the Riesz pair's rotation, the loop filter's fit and filter, the bandelet search
    of the squares (serial and parallel). Decoding the files first would compile the coders, which
    the encoder needs at once and compiles itself meanwhile: the same kernel compiled twice, while
    the encoder's later ones wait (a first encode of a 512 x 512 map: BENCHMARKS, "The first run")."""
    import numpy as np

    from ..restore import loopfilter
    from ..restore.precisions import compile_both
    from ..search.lagrangian import best_directions

    compile_both()
    rng = np.random.default_rng(0)
    decoded = rng.standard_normal((2, 64, 64))
    target = 0.5 * decoded + 0.25 * (np.roll(decoded, 1, 1) + np.roll(decoded, 1, 2))  # a filter pays
    loopfilter.choose(decoded, target, 0.5, 0.1, lambda c: float(np.sum((c - target) ** 2)))
    best_directions(rng.standard_normal((2, 256, 256)), 8, 0.5)  # enough work to run in parallel
    best_directions(rng.standard_normal((2, 8, 8)), 4, 0.5)  # too little: in one thread


def _make() -> None:
    """Write the files of :data:`FILES` from the generated maps (a change of the format needs them
    again: ``tests/test_warmup.py`` fails until then)."""
    import numpy as np

    from ..samples import bevel_normal_map, crease_normal_map
    from .encoder import encode

    crease, bevel = crease_normal_map(64), bevel_normal_map(64)
    samples = np.clip(np.rint(crease * 127.5 + 127.5), 0, 255).astype(np.uint8)
    files = {
        "lifted": encode(crease, bpp=2, kind="normal-map"),
        "filtered": encode(bevel, bpp=2, kind="normal-map", riesz=False),
        "riesz": encode(bevel, bpp=1, kind="normal-map", riesz=True),
        "lossless": encode(samples, kind="normal-map", lossless=True),
    }
    for name, data in files.items():
        (FILES / f"{name}.bdl").write_bytes(data)


if __name__ == "__main__":
    _make() if sys.argv[1:] == ["--make"] else warm_up()
