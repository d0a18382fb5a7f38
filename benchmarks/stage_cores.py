"""Where the wall time of one encode and one decode goes, stage by stage, and how many cores each keeps busy.

A thread samples the calling thread's stack every 20 ms and the process's CPU time (all its threads,
``/proc/self/task``): each sample's wall and CPU time go to the chain of the encoder's stages on the
stack (:data:`STAGES`, innermost three). A stage whose CPU time is its wall time ran on one core.
Linux only (``/proc``); the CPU clock ticks at 10 ms, so a short stage's share is rough. Run it with
the machine otherwise idle: another process's load shows as a stage on fewer cores.

    python benchmarks/stage_cores.py --map boombox_2048 [--bpp 1] [--upscale 4096]
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import threading
import time
from pathlib import Path

import bandelets

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rd_normal_maps import load  # noqa: E402
from speed import _upscaled  # noqa: E402

#: The functions (by name) whose chain on the stack names a sample's stage.
STAGES = frozenset(
    "plan_image wavelet_coefficients levels_to_try lifted riesz_pair _lossless _make_measures _cheapest "
    "_probe best_trees _prices optimise_bins apply_trees code_image with_restoration iterate measure "
    "with_loop_filter decode decoded_bins decoded_from_bins synthesis analysis decoded_image".split()
)
_TICK = os.sysconf("SC_CLK_TCK")


def _cpu_seconds() -> float:
    """CPU time of all the process's threads (user and system)."""
    total = 0
    for task in os.listdir("/proc/self/task"):
        try:
            fields = Path(f"/proc/self/task/{task}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:  # a thread that ended meanwhile
            continue
        total += int(fields[11]) + int(fields[12])
    return total / _TICK


class _Sampler:
    """Wall and CPU seconds per stage of what ``thread`` runs while the ``with`` block lasts."""

    def __init__(self, thread: threading.Thread) -> None:
        self.ident, self.stop = thread.ident, threading.Event()
        self.wall: collections.Counter = collections.Counter()
        self.cpu: collections.Counter = collections.Counter()

    def _stage(self) -> str:
        frame, chain = sys._current_frames().get(self.ident), []
        while frame is not None:
            if "bandelets" in frame.f_code.co_filename and frame.f_code.co_name in STAGES:
                chain.append(frame.f_code.co_name)
            frame = frame.f_back
        return ">".join(reversed(chain[:3])) or "(other)"

    def _run(self) -> None:
        wall, cpu = time.perf_counter(), _cpu_seconds()
        while not self.stop.wait(0.02):
            stage, now, used = self._stage(), time.perf_counter(), _cpu_seconds()
            self.wall[stage] += now - wall
            self.cpu[stage] += used - cpu
            wall, cpu = now, used

    def __enter__(self) -> _Sampler:
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.thread.join()

    def report(self, title: str, rows: int) -> None:
        wall, cpu = sum(self.wall.values()), sum(self.cpu.values())
        print(f"{title}: wall {wall:.2f} s, CPU {cpu:.2f} s ({cpu / wall:.2f} cores)")
        for stage, seconds in self.wall.most_common(rows):
            used = self.cpu[stage]
            print(f"  {seconds:7.2f} {used:7.2f} {used / max(seconds, 1e-9):5.2f}  {stage}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", default="boombox_2048", help="a shared real map (NAME.png of --maps)")
    parser.add_argument("--maps", type=Path, default=Path("../shared/data/normal-maps"))
    parser.add_argument("--bpp", type=float, default=1.0)
    parser.add_argument("--upscale", type=int, default=0, help="upscaled bicubically to this side")
    parser.add_argument("--rows", type=int, default=25, help="stages shown, the longest first")
    args = parser.parse_args()
    samples = _upscaled(load(args.maps / f"{args.map}.png"), args.upscale)
    bandelets.decode(bandelets.encode(samples[:64, :64], threshold=0.05, kind="normal-map"))  # compiled
    print("seconds: wall, CPU, cores busy, stage (innermost three)")
    with _Sampler(threading.current_thread()) as sampled:
        data = bandelets.encode(samples, bpp=args.bpp, kind="normal-map")
    sampled.report(f"encode at {args.bpp:g} bpp, {len(data)} bytes", args.rows)
    with _Sampler(threading.current_thread()) as sampled:
        bandelets.decode(data)
    sampled.report("decode", args.rows)


if __name__ == "__main__":
    main()
