"""Kernels compiled in a second process while a first run's encoder compiles its own.

A fresh install compiles every numba kernel on its first call, on one core: about 100 s of CPU for
the first encode of a 512 x 512 map. So when the command line hears the first compilation of a run
(:mod:`bandelets.runtime.compilation`), it starts this module as a process of its own, which
compiles on the other core, on small arrays, what the encoder needs once it has compiled its first
kernels (the lossless estimate, the plain lifting, the coefficient coder: about 40 s), in the order
it needs them: the approximation's coder, the squares' search, the lifting along directions, the
squares' transform, then the restoration, the measures and the loop filter. The encoder then loads
them from numba's cache instead of compiling them. Once the coefficient coder is cached, it decodes
the few small files of ``warmup_files/`` (a lifted normal map with its restoration, one with a loop
filter, a Riesz pair, a lossless file): the decoder's own kernels, for the decode that follows. The
first encode of the vent decal map took 54 to 58 s of wall, about 50 s of CPU in each process,
against 67 s before this order (BENCHMARKS.md, "The first run").

Numba writes each cache file whole (a temporary file renamed), so two processes compiling at once
never leave a broken kernel; at worst a kernel compiled by both is compiled twice. Numba offers
no such warm-up, and shipping compiled kernels would tie the package to one CPU and one numba.

    python -m bandelets.codec.warmup          # what the first run starts
    python -m bandelets.codec.warmup --make   # the files again, after a change of the format
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from ..runtime.compilation import COMPILING
from .decoder import decode

__all__ = ["FILES", "warm_up"]

#: The files decoded, in this order (the coders and the restoration first: the encoder needs them
#: soonest).
FILES = Path(__file__).with_name("warmup_files")
_NAMES = ("lifted", "filtered", "riesz", "lossless")


#: The longest the warm-up waits for the first run to compile the coefficient coder, in seconds.
WAIT = 90.0


def warm_up() -> None:
    """Compile, on small arrays, the kernels a first encode reaches after the coefficient coder, in
    the order it reaches them (:func:`_next_kernels`, then :func:`_late_kernels`), then, once the
    coefficient coder is compiled (:func:`_await_coefficient_coder`), decode every file of
    :data:`FILES` (with and without the restoration, and at level 1)."""
    _next_kernels()
    _late_kernels()
    _await_coefficient_coder()
    for name in _NAMES:
        data = (FILES / f"{name}.bdl").read_bytes()
        decode(data)
        if name != "lossless":
            decode(data, restore=False)
            decode(data, level=1)


def _next_kernels() -> None:
    """What a first encode needs as soon as its coefficient coder is compiled (the first 40 s of a
    512 x 512 map's, spent on the lossless estimate, the plain lifting and that coder): the
    approximation's coder, the bandelet search of the squares (serial and parallel), the lifting
    along directions and its search's costs, the bandelet transform of the squares (in the layouts
    the encoder gives them). Decoding the files instead would compile the coders the encoder is
    compiling: the same kernel twice, while the encoder's later ones wait (BENCHMARKS, "The first
    run")."""
    import numpy as np

    from ..coding import approximation
    from ..coding.order import approximation_plan
    from ..coding.rangecoder import Coder
    from ..search.lagrangian import best_directions
    from ..transform import directional
    from ..transform.bandeletize import bandeletize
    from ..transform.lifting import direction_costs
    from ..transform.quadtree import flat_quadtree

    rng = np.random.default_rng(0)
    q = rng.integers(-3, 4, 256).astype(np.int32)
    approximation.code_approximation(
        Coder(approximation.N_CONTEXTS), q, approximation_plan((16, 16), 2), np.zeros(256, np.int64),
        np.zeros(0, np.int32), np.zeros(256),
    )  # fmt: skip
    best_directions(rng.standard_normal((2, 8, 8)), 4, 0.5)  # too little to run in parallel
    best_directions(rng.standard_normal((2, 256, 256)), 8, 0.5)  # enough
    x = rng.standard_normal((64, 64))
    direction_costs(x, directional.OFFSETS, directional.WEIGHTS, directional.SCALES, directional.BLOCK, 0.1)
    fields = [np.zeros(shape, np.int64) for shape in directional.field_shapes(x.shape, 2)]
    directional.transform(x, 3, 2, fields)
    pair = rng.standard_normal((16, 32))
    tree = flat_quadtree((16, 16), 8)
    tree.direction[-1][...] = 0  # every square along a direction: transformed
    bandeletize(pair[:, :16], tree, out=pair[:, 16:])


def _late_kernels() -> None:
    """The kernels a first encode reaches last, in its order: the restoration in both precisions and
    the Riesz pair's rotation, the measure of a normal map's decoded channels (in both precisions),
    the loop filter's fit and filter."""
    import numpy as np

    from ..metrics import psnr_of_channels
    from ..restore import loopfilter
    from ..restore.precisions import compile_both

    compile_both()
    rng = np.random.default_rng(0)
    measure = psnr_of_channels(rng.standard_normal((8, 8, 3)), "normal-map", 8)
    measure(rng.standard_normal((3, 8, 8)))
    measure(rng.standard_normal((3, 8, 8)).astype(np.float32))
    decoded = rng.standard_normal((2, 64, 64))
    target = 0.5 * decoded + 0.25 * (np.roll(decoded, 1, 1) + np.roll(decoded, 1, 2))  # a filter pays
    loopfilter.choose(decoded, target, 0.5, 0.1, lambda c: float(np.sum((c - target) ** 2)))


def _await_coefficient_coder() -> None:
    """Wait, at most :data:`WAIT` seconds and while the process that started this one runs
    (:data:`bandelets.runtime.compilation.COMPILING`; no wait without it), until the coefficient
    coder is in numba's cache.

    Every file's decode needs it, and the first run compiles it early (a first encode: after the
    lossless estimate and the plain lifting), about 18 s of CPU: decoding meanwhile compiled it a
    second time, on the core that would have compiled the encoder's later kernels (the first encode
    of a 512 x 512 map: BENCHMARKS, "The first run"). Numba writes a kernel's cache index whole
    once it is compiled, and loads it from there at the decode's first call."""
    from ..coding.coefficients import _coefficients

    compiling = os.environ.get(COMPILING, "")
    if not compiling.isdigit():  # run by hand or by a test: nobody else compiles it
        return
    try:
        index = _coefficients._cache._cache_file  # numba's own, not public: without it, no wait
        end = time.monotonic() + WAIT
        while not index._load_index() and time.monotonic() < end and _alive(int(compiling)):
            time.sleep(0.5)
    except AttributeError:
        pass


def _alive(pid: int) -> bool:
    """Whether the process ``pid`` still runs (the one compiling the coefficient coder)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's: it runs
        pass
    return True


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
