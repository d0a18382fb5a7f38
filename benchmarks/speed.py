"""Speed of the codec beside OpenJPEG and AVIF, on the same image, in one run.

For a generated crease normal map of each size: the median over ``--repeat`` runs of
bandelet encode at 1 bpp (rate control and the encoder's restoration search included), decode
(restoration as the file asks) and decode without restoration, with OpenJPEG (JPEG2000,
16-bit) and libavif (12-bit, speed 6) encode and decode times on the same map through
imagecodecs, and the ratios (the figures to quote: the machine may be shared); also the
process CPU time of the bandelet runs (all threads). A size the default memory limits refuse
is reported with the refusal. Before that, the cold start: import, compilation of every numba
kernel (empty cache) and a small encode. Then the time per pixel against the 512 x 512 one;
with ``--memory``, the peak resident memory of an encode and of a decode of each size (each in
a child process whose high-water mark is reset once the map or file is made, Linux only; from
8192 x 8192 on, the map is held as 8-bit samples, as read from a PNG: its float64 array alone
would take 1.5 GiB). Maps are coded as the library's default does (in one piece when that fits
the memory limit, in tiles of 512 above: :func:`bandelets.format.limits.tile_side`), or in tiles of
``--tile`` at any size. ``--map bevel``: the generated 8-bit bevel map instead
(:func:`bandelets.samples.bevel_normal_map`, given to us as its samples, to the anchors as its
vectors, as the crease map is), whose files are Riesz pairs (:mod:`bandelets.transform.riesz`); with
``--no-riesz``, its channels.

``--real``: then the shared real maps of ``--maps`` (:data:`REAL`, or those named; ``--upscale N``:
upscaled bicubically to N pixels a side, as issue 36's 4096 x 4096 boombox), given as
their 8-bit samples (as ``benchmarks/rd_normal_maps.py`` reads them; ``--floats``: as unit
vectors made from them, as ``../shared/tools/quick-speed.py`` gives them); a map whose file is
absent is skipped with a message. AVIF is timed at speed 6 and at speed 2 (the anchor of the
rate-distortion tables) on every map. ``--stages``: after the timed runs, one more encode of each
map under cProfile, its CPU time split into the encoder's stages (:data:`STAGES`: the direction
search of the bandelet squares, the lifting's directions, the Riesz pair's choice, the
coefficients' coding, the restoration search, the loop filter; each stage's cumulative time,
which the profiler inflates a little) with the count of rate-control loops and of full encodes.

    python benchmarks/speed.py [--sizes 512,2048,4096] [--repeat 3] [--memory] [--no-cold-start] [--tile 512]
    python benchmarks/speed.py --map bevel --sizes 512 [--no-riesz]
    python benchmarks/speed.py --sizes 512 --real [--repeat 5] [--memory] [--stages] [--floats]
    python benchmarks/speed.py --sizes none --real godot_scifi_vent_decal_512 --stages
    python benchmarks/speed.py --sizes none --real boombox_2048 --upscale 4096 --repeat 1 --memory
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import statistics
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import imagecodecs
import numpy as np

import bandelets
from bandelets.format.container import header_of
from bandelets.format.limits import check_encodable
from bandelets.format.samples import from_samples
from bandelets.samples import bevel_normal_map, crease_normal_map

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_normal_maps import load  # noqa: E402

#: ``--real``: the shared real maps timed (files ``NAME.png`` of ``--maps``).
REAL = (
    "godot_scifi_vent_decal_512",
    "flighthelmet_leather_512",
    "learnwgpu_cobblestone_1024",
    "boombox_2048",
)
#: ``--stages``: the encoder's stages, each the functions (by name) whose cumulative time it is.
#: Rate control is the whole of its loop (its encodes, the restoration search and the loop filter's fit
#: of the file kept); the "of which" stages are parts of it or of the other stages (the direction search
#: of the squares and the coding run wherever a file is made); "rest" is what no other stage holds.
STAGES = {
    "rate control (its encodes)": ("_search_size",),
    "of which direction search (squares)": ("best_directions",),
    "of which coding": ("code_image", "code_lifting"),
    "of which restoration search": ("with_restoration",),
    "of which loop filter": ("with_loop_filter",),
    "lifting directions": ("lifted",),
    "Riesz pair choice": ("riesz_pair",),
    "weighing the alternatives": ("_cheapest",),
    "level choice": ("levels_to_try",),
    "lossless try": ("_lossless",),
}

#: ``--map``: the source of each size, as the memory's child process makes it.
MAPS = {
    "crease": "crease_normal_map({size}, supersampling={supersampling})",
    "bevel": "bevel_normal_map({size})",
}


def _median_seconds(run, repeat: int, cpu: list | None = None) -> float:
    """Median wall time of ``run()``; its median process CPU time appended to ``cpu``."""
    times, used = [], []
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        run()
        times.append(time.perf_counter() - start)
        used.append(time.process_time() - start_cpu)
    if cpu is not None:
        cpu.append(statistics.median(used))
    return statistics.median(times)


def _cold_start_seconds() -> float:
    """Import, encode and decode of a 64 x 64 map in a new process whose numba cache is empty:
    every kernel compiled (the cost of the very first run after installing)."""
    code = (
        "import time; t = time.perf_counter(); import bandelets; "
        "from bandelets.samples import crease_normal_map; "
        "bandelets.decode(bandelets.encode(crease_normal_map(64), threshold=0.05, kind='normal-map')); "
        "print(time.perf_counter() - t)"
    )
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        command = [sys.executable, "-c", code]
        out = subprocess.run(command, capture_output=True, text=True, env=env, check=True)
    return float(out.stdout.split()[-1])


def _source(name: str, size: int) -> tuple[np.ndarray, np.ndarray]:
    """What ``bandelets.encode`` is given for ``--map name``, and its unit vectors."""
    if name == "bevel":
        samples = bevel_normal_map(size)
        return samples, from_samples(samples, "normal-map", 8)
    normals = crease_normal_map(size, supersampling=1 if size > 1024 else 4)
    return normals, normals


def _peak_memory_mib(
    size: int, what: str, tile: int, name: str = "crease", riesz: bool | None = None, real: str = ""
) -> str:
    """Peak resident memory of a process during one bandelet encode at 1 bpp or one decode of
    that file (Linux: VmHWM, reset after the map, or the file, is made so that only the
    measured call counts; imports included), or the one-line error that refused it. ``real``:
    the Python expression of a real map (``n``) instead of the generated one."""
    make = (
        "import bandelets, sys; from bandelets.samples import bevel_normal_map, crease_normal_map; "
        + (real or f"n = {MAPS[name].format(size=size, supersampling=1)}")
        + "; "
    )
    if size >= 8192 and name == "crease" and not real:
        make += "import numpy as np; n = np.round((n + 1) * 127.5).astype(np.uint8); "
    encode = f"bandelets.encode(n, bpp=1, kind='normal-map', tile={tile}, riesz={riesz})"
    if what == "decode":
        make += f"data = {encode}; "
    call = encode if what == "encode" else "bandelets.decode(data)"
    code = (
        make
        + "open('/proc/self/clear_refs', 'w').write('5')\n"
        + f"try:\n    {call}\nexcept ValueError as e:\n    print('refused:', e); sys.exit()\n"
        + "print([l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    last = out.stdout.strip().splitlines()[-1]
    return last if last.startswith("refused") else f"{int(last) / 1024:.0f} MiB"


def _fits(size: int) -> str | None:
    """The error that refuses a size x size x 3 encode under the default limits, if any."""
    try:
        check_encodable(size, size, 3)
    except ValueError as err:
        return str(err)
    return None


def _stages(encode) -> str:
    """One ``encode()`` under cProfile: the seconds of each of :data:`STAGES` (cumulative, summed
    over the functions of that name in the package), the encodes and rate-control loops. The
    profiler's clock is the process's CPU time (all threads): on a shared machine the wall time of
    a stage measures the other processes as much as the stage."""
    profile = cProfile.Profile(time.process_time)
    start, wall = time.process_time(), time.perf_counter()
    profile.runcall(encode)
    total, wall = time.process_time() - start, time.perf_counter() - wall
    stats = pstats.Stats(profile).stats  # (file, line, name) -> (calls, primitive, own, cumulative, callers)

    def of(*names: str, column: int = 3) -> float:
        return sum(v[column] for (path, _, name), v in stats.items() if name in names and "bandelets" in path)

    parts = ", ".join(f"{stage} {of(*names):.2f} s" for stage, names in STAGES.items())
    rest = total - sum(of(*names) for stage, names in STAGES.items() if not stage.startswith("of which"))
    encodes = of("encode_at_threshold", column=0) - of("_probe", column=0)
    return (
        f"stages of a profiled encode (CPU {total:.2f} s, wall {wall:.2f} s), CPU: {parts}, "
        f"rest {rest:.2f} s; {of('_search_size', column=0):.0f} rate-control loops, {encodes:.0f} full "
        f"encodes and {of('_probe', column=0):.0f} wavelet probes"
    )


def _row(label: str, source, j2k: np.ndarray, avif: np.ndarray, depth: int, args, peak=None) -> float:
    """Time and print one map: the bandelet encode at 1 bpp of ``source`` (medians of
    ``args.repeat``), its decode with and without the restoration, OpenJPEG's of the samples
    ``j2k`` and AVIF's (speeds 6 and 2) of ``avif``, samples of ``depth`` bits; ``peak``: the
    peak memory's measure, if any. Returns the encode's seconds."""
    cpu: list[float] = []
    encode = partial(bandelets.encode, source, bpp=1, kind="normal-map", tile=args.tile, riesz=args.riesz)
    data = encode()
    rated = _median_seconds(encode, args.repeat, cpu)
    decode = _median_seconds(partial(bandelets.decode, data), args.repeat, cpu)
    plain = _median_seconds(partial(bandelets.decode, data, restore=False), args.repeat, cpu)
    j2k_encode = partial(
        imagecodecs.jpeg2k_encode, j2k, level=50, reversible=False, mct=False, codecformat="j2k"
    )
    avif_encode = partial(imagecodecs.avif_encode, avif, level=80, bitspersample=depth, pixelformat="444")
    times = [
        _median_seconds(j2k_encode, args.repeat),
        _median_seconds(partial(imagecodecs.jpeg2k_decode, j2k_encode()), args.repeat),
        _median_seconds(partial(avif_encode, speed=6), args.repeat),
        _median_seconds(partial(imagecodecs.avif_decode, avif_encode(speed=6)), args.repeat),
        _median_seconds(partial(avif_encode, speed=2), args.repeat),
    ]
    pixels = source.shape[0] * source.shape[1]
    print(
        f"{label:>26} {rated:>9.3f} {decode:>8.3f} {plain:>9.3f} "
        + " ".join(f"{t:>8.3f}" for t in times)
        + f" {rated / pixels * 1e6:>10.3f}"
    )
    header = header_of(data)
    print(
        f"      {len(data)} bytes ({8 * len(data) / pixels:.3f} bpp), {header.restoration} restoration "
        f"iterations (the most of any tile), Riesz pair {header.riesz}; bandelets CPU time (all threads): "
        f"1 bpp {cpu[0]:.3f} s, decode {cpu[1]:.3f} s, plain decode {cpu[2]:.3f} s"
    )
    print(
        f"      ratios to OpenJPEG in this run: encode x{rated / times[0]:.1f}, "
        f"decode x{decode / times[1]:.1f}, plain decode x{plain / times[1]:.1f}; "
        f"to AVIF speed 6: encode x{rated / times[2]:.1f}, decode x{decode / times[3]:.1f}; "
        f"to AVIF speed 2: encode x{rated / times[4]:.1f}"
    )
    if args.stages:
        print(f"      {_stages(encode)}")
    if peak is not None:
        print(f"      peak RSS: encode {peak('encode')}, decode {peak('decode')}")
    return rated


def _upscaled(samples: np.ndarray, side: int) -> np.ndarray:
    """``samples`` (8-bit) upscaled bicubically (Pillow's) to ``side`` pixels a side (0: as they are)."""
    if not side:
        return samples
    from PIL import Image

    return np.asarray(Image.fromarray(samples).resize((side, side), Image.BICUBIC))


def _real_maps(args) -> None:
    """Time the real maps of ``args.real`` (those absent skipped with a message)."""
    for name in args.real.split(","):
        path = args.maps / f"{name}.png"
        if not path.is_file():
            print(f"{name:>26} skipped: {path} is absent (see --maps)")
            continue
        samples = _upscaled(load(path), args.upscale)
        source = samples / 255.0 * 2 - 1 if args.floats else samples
        real = (
            f"sys.path.insert(0, {str(Path(__file__).resolve().parent)!r}); from rd_normal_maps import load; "
        )
        real += "from pathlib import Path; from speed import _upscaled; "
        real += f"n = _upscaled(load(Path({str(path)!r})), {args.upscale})"
        real += "; n = n / 255.0 * 2 - 1" if args.floats else ""
        peak = None
        if args.memory:
            peak = partial(_peak_memory_mib, samples.shape[0], tile=args.tile, riesz=args.riesz, real=real)
        _row(name if not args.upscale else f"{name}@{args.upscale}", source, samples, samples, 8, args, peak)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="256,512,1024,2048")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--tile",
        type=int,
        default=0,
        help="tile side (bandelets.format.container; default 0: the library's choice)",
    )
    parser.add_argument("--memory", action="store_true", help="peak RSS of an encode and a decode per size")
    parser.add_argument(
        "--no-cold-start", action="store_true", help="skip the cold start (empty numba cache)"
    )
    parser.add_argument("--map", choices=sorted(MAPS), default="crease", help="the map timed")
    parser.add_argument(
        "--no-riesz", dest="riesz", action="store_false", default=None, help="code the channels, not a pair"
    )
    parser.add_argument(
        "--real",
        nargs="?",
        const=",".join(REAL),
        default="",
        help="then the shared real maps (default: all of REAL; or names, comma-separated)",
    )
    parser.add_argument("--maps", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--floats", action="store_true", help="real maps given as unit vectors, not samples")
    parser.add_argument(
        "--upscale", type=int, default=0, help="real maps upscaled bicubically to this side (4096: issue 36)"
    )
    parser.add_argument("--stages", action="store_true", help="a profiled encode's stages per map")
    args = parser.parse_args()
    if not args.no_cold_start:
        print(
            f"cold start (import, compile every kernel, encode + decode 64^2): {_cold_start_seconds():.2f} s"
        )
    start = time.perf_counter()
    bandelets.decode(bandelets.encode(crease_normal_map(64), threshold=0.05, kind="normal-map"))
    print(f"first call (numba cache load or compile): {time.perf_counter() - start:.2f} s")
    print(
        f"{'map':>26} {'bdl 1bpp':>9} {'bdl dec':>8} {'plain dec':>9} {'j2k enc':>8} {'j2k dec':>8} "
        f"{'avif6 enc':>8} {'avif dec':>8} {'avif2 enc':>8} {'us/px 1bpp':>10}"
    )
    per_pixel = {}
    for size in (int(s) for s in args.sizes.split(",") if s.isdigit()):
        refused = _fits(size)
        if refused:
            print(f"{size:>26} refused under the default limits: {refused}")
            continue
        source, normals = _source(args.map, size)
        peak = None
        if args.memory:
            peak = partial(_peak_memory_mib, size, tile=args.tile, name=args.map, riesz=args.riesz)
        # OpenJPEG is given 16-bit samples, AVIF 12-bit ones (its most).
        u16 = np.round((normals + 1) / 2 * 65535).astype(np.uint16)
        u12 = np.round((normals + 1) / 2 * 4095).astype(np.uint16)
        rated = _row(f"{args.map} {size}", source, u16, u12, 12, args, peak)
        per_pixel[size] = rated / size**2 * 1e6
    if args.real:
        _real_maps(args)
    if 512 in per_pixel:
        for size, value in per_pixel.items():
            print(f"time per pixel at {size}: {value / per_pixel[512]:.2f} x the 512 one")


if __name__ == "__main__":
    main()
