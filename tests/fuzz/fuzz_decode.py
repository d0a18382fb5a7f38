"""Coverage-guided fuzzing of ``bandelets.decode`` with atheris (libFuzzer).

    pip install atheris
    python tests/fuzz/fuzz_decode.py -runs=100000 /tmp/bdl-corpus

The corpus folder is created and seeded with the golden files of ``tests/data`` (without
their CRC) when it holds none. An input is the body of a .bdl file: the harness appends a
valid CRC32, so the mutations reach the header validation and the range decoders instead of
dying at the CRC check; the custom mutator also repairs the third stream length after
mutations that change the size, half of the time. Every input is also decoded as it is.

A crash is anything but a return or a ``ValueError`` (``bandelets.FormatError`` is one), a
decoded array of the wrong shape or with non-finite values, or a decode slower than
2 s (with ``BDL_FUZZ_SLOW=record`` in the environment, slow inputs are kept as
``slow-N.bdl`` and counted instead). Limits are small (``max_side`` 256, 2**16 samples,
32 MiB, 2**20 sample-iterations of restoration) so that no input can legitimately take long.
Every 10,000 inputs and at the last of ``-runs`` the harness prints the number of inputs, the
outcomes and the slowest input (written to ``slowest.bdl`` in the current folder).

libFuzzer options apply (``-runs``, ``-max_total_time``, ``-jobs``, ``-max_len``...).
Coverage is Python coverage: the numba-compiled range decoder is not instrumented, the code
that drives it is.
"""

from __future__ import annotations

import collections
import importlib
import importlib.util
import os
import re
import struct
import sys
import time
import zlib
from pathlib import Path

import atheris
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/, for headerints
from headerints import integer_count, leb128, read_integers  # noqa: E402


def _import_compiled_modules() -> None:
    """Import, plain, every module of the package that compiles functions with numba: numba
    cannot compile what atheris instruments (``Unknown attribute '_trace_branch'``)."""
    source = Path(importlib.util.find_spec("bandelets").origin).parent
    for path in sorted(source.rglob("*.py")):
        if re.search(r"^(from|import) numba\b", path.read_text(), re.MULTILINE):
            name = ".".join(path.relative_to(source.parent).with_suffix("").parts)
            importlib.import_module(name)


_import_compiled_modules()
with atheris.instrument_imports(include=["bandelets"]):
    import bandelets
    import bandelets.codec.encoder  # imported lazily by the package: import it here to instrument it
    from bandelets.format.fields import KIND_CODES, MAX_LEVELS, WAVELETS, FormatError
    from bandelets.format.header import streams_offset, unpack
    from bandelets.transform.wavelets import subband_norms

LIMITS = {"max_side": 256, "max_samples": 2**16, "max_memory": 32 * 2**20, "max_work": 2**20}
MAX_SECONDS = 2.0
#: BDL_FUZZ_SLOW=record: keep slow inputs as slow-N.bdl and go on instead of stopping.
RECORD_SLOW = os.environ.get("BDL_FUZZ_SLOW") == "record"
KIND_OF = {code: kind for kind, code in KIND_CODES.items()}  # the header's kind byte (offset 5)
DATA = Path(__file__).resolve().parents[1] / "data"

stats = collections.Counter()
slowest = [0.0, b""]
REPORT_EVERY = 10_000
runs = [0]  # the -runs=N option, to report before libFuzzer exits (it skips atexit)


def with_crc(body: bytes) -> bytes:
    return body + struct.pack("<I", zlib.crc32(body))


def run(data: bytes) -> None:
    start = time.perf_counter()
    try:
        out = bandelets.decode(data, **LIMITS)
    except FormatError as err:
        reason = re.sub(r"-?\b\d[0-9.e+-]*|nan|inf", "N", str(err).split(": ", 1)[-1])
        stats["FormatError: " + reason[:50]] += 1
    except ValueError as err:  # allowed by the contract, but worth knowing about
        stats[f"other ValueError {type(err).__name__}: {str(err)[:60]}"] += 1
    else:
        stats["decoded"] += 1
        header = unpack(data, max_side=2**32, max_samples=2**64)[0]  # it decoded: it parses
        channels = header.channels
        if header.kind == "normal-map":  # z rebuilt from x, y, unless the source was x, y alone
            channels = 2 if header.layout == "xy" else 3
        h, w = header.height, header.width
        expected = (h, w) if channels == 1 else (h, w, channels)
        if out.shape != expected or out.dtype != np.float64 or not np.all(np.isfinite(out)):
            raise AssertionError(f"bad output {out.shape} {out.dtype} for header {expected}")
    elapsed = time.perf_counter() - start
    if elapsed > slowest[0]:
        slowest[:] = [elapsed, data]
    if elapsed > MAX_SECONDS:
        if not RECORD_SLOW:
            raise AssertionError(f"decode took {elapsed:.2f} s (limit {MAX_SECONDS} s)")
        stats[f"SLOW (> {MAX_SECONDS} s), kept as slow-*.bdl"] += 1
        Path(f"slow-{stats['inputs']}.bdl").write_bytes(data)


def test_one_input(body: bytes) -> None:
    stats["inputs"] += 1
    run(body)
    run(with_crc(body))
    if stats["inputs"] % REPORT_EVERY == 0 or stats["inputs"] == runs[0]:
        report()


def repair_lengths(body: bytes) -> bytes:
    """``body`` with its last segment length (the header's last LEB128 integer, format version 19:
    :func:`headerints.integer_count` of them) fitted to its size, when it can be."""
    try:
        start = streams_offset(body)
    except FormatError:
        return body
    values, at = read_integers(body, 14, integer_count(body))  # which streams_offset found well formed
    last = len(body) - start - sum(values[2:-1])  # the same whatever bytes its integer takes
    if last < 0:
        return body
    return body[: at - len(leb128(values[-1]))] + leb128(last) + body[at:]


def custom_mutator(data: bytes, max_size: int, seed: int) -> bytes:
    data = atheris.Mutate(data, max_size)
    return repair_lengths(data) if seed & 1 else data


def seed_corpus(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    if any(folder.iterdir()):
        return
    for path in sorted(DATA.glob("*.bdl")):
        (folder / path.name).write_bytes(path.read_bytes()[:-4])


def report() -> None:
    out = sys.stderr
    print(f"\n[fuzz_decode] {stats['inputs']} inputs (each decoded raw and with a valid CRC)", file=out)
    for key, n in stats.most_common():
        if key != "inputs":
            print(f"[fuzz_decode]   {n:8d}  {key}", file=out)
    print(f"[fuzz_decode] slowest decode {slowest[0]:.3f} s ({len(slowest[1])} bytes, slowest.bdl)", file=out)
    Path("slowest.bdl").write_bytes(slowest[1])


def main() -> None:
    folders = [a for a in sys.argv[1:] if not a.startswith("-")]
    for folder in folders:
        seed_corpus(Path(folder))
    # Compile the JIT code and compute the per-process caches (the synthesis norms of every
    # wavelet and depth: seconds for 6 levels) before the clock of the first input starts: an
    # ordinary encode and decode (issue 40's condition: kernels such as the lifting's passes over
    # strided views are specialised by the encoder, not by the golden files), then the golden files.
    from bandelets.samples import bump_normal_map, crease_normal_map

    for normals in (crease_normal_map(128), bump_normal_map(64)):
        three = np.concatenate([normals[..., :2] * 0.9, -np.abs(normals[..., 2:])], axis=-1)
        for x in (normals, three):
            bandelets.decode(bandelets.encode(x, bpp=1.0, kind="normal-map"))
    for path in sorted(DATA.glob("*.bdl")):
        bandelets.decode(path.read_bytes())
    for wavelet in WAVELETS:
        for levels in range(1, MAX_LEVELS + 1):
            subband_norms(wavelet, levels)
    runs[0] = next((int(a.split("=", 1)[1]) for a in sys.argv if a.startswith("-runs=")), 0)
    atheris.Setup(sys.argv, test_one_input, custom_mutator=custom_mutator)
    atheris.Fuzz()


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    import warnings

    warnings.simplefilter("ignore")
    main()
