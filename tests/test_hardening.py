"""Hostile files and inputs: a bounded slice of the fuzzing of tests/fuzz/fuzz_decode.py.

Every case must end in a return or a ValueError (FormatError is one), within 2 s; the memory
estimate refuses, before allocating, files and inputs too large for ``max_memory``.
"""

from __future__ import annotations

import collections
import struct
import subprocess
import sys
import time
import tracemalloc
import warnings
import zlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from headerints import integer_count, leb128, read_integers

import bandelets
from bandelets.format import container
from bandelets.format.fields import MAX_MEMORY, FormatError
from bandelets.format.header import Header, implied_options, pack, streams_offset, unpack
from bandelets.format.limits import decoder_memory, encoder_memory
from bandelets.samples import crease_normal_map

DATA = Path(__file__).resolve().parent / "data"
# Files of one tile, whose layout the repair knows (a tiled file: test_tiled_file_mutations).
GOLDEN = sorted(p for p in DATA.glob("*.bdl") if not p.stem.endswith("-tiled"))
TILED = DATA / "normal24x20-tiled.bdl"
SMALL = {"max_side": 256, "max_samples": 2**16, "max_memory": 32 * 2**20, "max_work": 2**20}
CASE_SECONDS = 2.0


def _crc(body: bytes) -> bytes:
    return body + struct.pack("<I", zlib.crc32(body))


def _outcome(data: bytes, **limits) -> str:
    """Decode; anything but a return or a ValueError, or a slow case, fails the test."""
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            out = bandelets.decode(data, **limits)
        except ValueError as err:
            result = type(err).__name__
        else:
            assert out.dtype == np.float64 and np.all(np.isfinite(out))
            result = "decoded"
    elapsed = time.perf_counter() - start
    assert elapsed < CASE_SECONDS, f"{elapsed:.2f} s on a {len(data)}-byte input"
    return result


def _repaired(body: bytearray) -> bytes:
    """``body`` with the last stream length fitted to its size (when possible; a file whose byte 8
    says it has a loop filter keeps a plausible section after its streams) and a valid CRC."""
    body = bytes(body)
    try:
        start = streams_offset(body)
    except FormatError:  # a header cut short or malformed: only the CRC
        return _crc(body)
    (_, _, *lengths), end = read_integers(body, 14, integer_count(body))  # after the 14 fixed bytes
    c = lengths[-1]  # the last segment's length is fitted
    rest = len(body) - start - sum(lengths[:-1])  # the same whatever bytes its LEB128 takes: start moves
    filtered = body[8] >= 128
    if rest >= 0 and not (filtered and 0 < rest - c <= 256):
        body = body[: end - len(leb128(c))] + leb128(rest) + body[end:]
    return _crc(body)


@pytest.mark.parametrize("path", GOLDEN, ids=lambda p: p.name)
def test_repairing_an_intact_file_changes_nothing(path):
    """The repair reaches the decoder: an unmodified golden file comes out of it unchanged."""
    data = path.read_bytes()
    assert _repaired(bytearray(data[:-4])) == data


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    for path in GOLDEN:  # JIT compile outside the clock of the cases
        bandelets.decode(path.read_bytes())


def test_random_garbage():
    rng = np.random.default_rng(1)
    outcomes = set()
    for i in range(600):
        n = int(rng.integers(0, 300))
        junk = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        if i % 3 == 1:
            junk = b"BDL\x1a\x01" + junk
        if i % 3 == 2:  # a plausible header, random streams, lengths and CRC made valid
            header = GOLDEN[i % len(GOLDEN)].read_bytes()
            junk = bytearray(header[: streams_offset(header)] + junk)
            junk = _repaired(junk)
        outcomes.add(_outcome(junk, **SMALL))
    assert "FormatError" in outcomes


@pytest.mark.parametrize("path", GOLDEN, ids=lambda p: p.name)
def test_truncations_behind_a_valid_crc(path):
    """Every truncation of the body, with the lengths and the CRC repaired: the decoders see it."""
    body = path.read_bytes()[:-4]
    outcomes = [_outcome(_repaired(bytearray(body[:n])), **SMALL) for n in range(len(body))]
    assert outcomes.count("FormatError") > len(body) // 2


@pytest.mark.parametrize("path", [DATA / "gray16.bdl", DATA / "normal24x20.bdl"], ids=lambda p: p.name)
def test_every_single_bit_flip_behind_a_valid_crc(path):
    body = path.read_bytes()[:-4]
    outcomes = set()
    for bit in range(8 * len(body)):
        b = bytearray(body)
        b[bit // 8] ^= 1 << (bit % 8)
        outcomes.add(_outcome(_crc(bytes(b)), **SMALL))
    assert {"decoded", "FormatError"} <= outcomes


def test_random_multi_byte_mutations():
    rng = np.random.default_rng(2)
    files = [p.read_bytes()[:-4] for p in GOLDEN]
    for i in range(600):
        b = bytearray(files[i % len(files)])
        for _ in range(int(rng.integers(1, 6))):
            at = int(rng.integers(0, len(b)))
            b[at] = int(rng.integers(0, 256))
        _outcome(_repaired(b), **SMALL)


def test_tiled_file_mutations():
    """Truncations, byte changes anywhere, and tile tables rewritten behind a valid CRC: each
    ends in a return or a ValueError, within the limits and the time of a case."""
    data = TILED.read_bytes()
    grid, _ = container.read(data)
    table_end = 20 + 4 * len(grid.boxes)
    outcomes = collections.Counter(_outcome(data[:n], **SMALL) for n in range(len(data)))
    rng = np.random.default_rng(7)
    for _ in range(200):
        mutated = bytearray(data)
        for at in rng.integers(0, len(data), rng.integers(1, 4)):
            mutated[at] = rng.integers(0, 256)
        outcomes[_outcome(bytes(mutated), **SMALL)] += 1
        if rng.random() < 0.5:  # the same, with the table's CRC made valid again
            struct.pack_into("<I", mutated, table_end, zlib.crc32(mutated[:table_end]))
            outcomes[_outcome(bytes(mutated), **SMALL)] += 1
    # A few bytes claiming 16384 x 16384 in tiles of 16: a million tiles, refused at once.
    head = struct.pack("<4sBBxxIII", b"BDL\x1a", data[4], 255, 16384, 16384, 16)
    assert _outcome(head + b"\x00" * 8) == "FormatError"
    assert set(outcomes) <= {"decoded", "FormatError", "ValueError"} and outcomes["FormatError"] > len(data)


@pytest.mark.parametrize(
    ("height", "width", "channels"),
    [(16384, 16384, 1), (8192, 8192, 4), (16384, 1, 1), (1, 16384, 3), (5000, 5000, 3), (2, 1, 1)],
)
def test_valid_header_with_absurd_sizes_and_tiny_streams(height, width, channels):
    """A 100-byte file claiming a huge image is refused at once by the memory estimate."""
    kind = "image" if channels != 3 else "normal-map"
    levels = 1
    header = Header(
        height=height,
        width=width,
        channels=channels,
        kind=kind,
        transform="bandelet",
        wavelet="cdf97",
        levels=levels,
        threshold=0.1,
        **implied_options(kind, channels),
    )
    data = pack(header, (b"\x00" * 20, b"\x00" * 20, b"\x00" * 20))
    start = time.perf_counter()
    need = decoder_memory(height, width, channels, levels, header.frames)
    if need > MAX_MEMORY:
        with pytest.raises(FormatError, match=r"needs about \d+ MiB, above the limit of 2048 MiB"):
            bandelets.decode(data)
    else:
        assert _outcome(data) in {"decoded", "FormatError"}
    assert time.perf_counter() - start < CASE_SECONDS


def test_memory_limit_is_overridable_and_exact():
    data = bandelets.encode(np.zeros((64, 48)), threshold=0.1)
    need = decoder_memory(64, 48, 1, 2)
    with pytest.raises(FormatError, match=r"needs about .* MiB, above the limit"):
        bandelets.decode(data, max_memory=need - 1)
    assert bandelets.decode(data, max_memory=need).shape == (64, 48)


def test_memory_estimate_covers_the_measured_peak():
    """The estimate is an upper bound of what tracemalloc sees the decoder allocate."""
    rng = np.random.default_rng(4)
    for shape in [(256, 256), (128, 192, 3)]:
        data = bandelets.encode(rng.random(shape), threshold=0.05)
        bandelets.decode(data)
        tracemalloc.start()
        bandelets.decode(data)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        channels = shape[2] if len(shape) == 3 else 1
        assert peak <= decoder_memory(shape[0], shape[1], channels, 4), (shape, peak)
        # The same streams, restored by the decoder.
        header, streams = unpack(data)
        restored = pack(replace(header, restoration=5), streams)
        bandelets.decode(restored)
        tracemalloc.start()
        bandelets.decode(restored)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak <= decoder_memory(shape[0], shape[1], channels, 4, restoration=True), (shape, peak)


def test_encoder_working_set_of_a_normal_map():
    """A default encode (rate control, directions, restoration search) holds no spare copies: the
    256 x 256 crease map at 1 bpp peaks at 187 B/pixel of numpy allocations (291 when rate control
    held the unit normals, the PSNR reference twice and every pass's code lengths), and within the
    estimate that chooses one piece or tiles."""
    normals = crease_normal_map(256)
    bandelets.encode(normals, bpp=1.0, kind="normal-map")  # kernels and tables: not counted
    tracemalloc.start()
    bandelets.encode(normals, bpp=1.0, kind="normal-map")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak <= 230 * 256 * 256, peak / 256**2
    assert peak <= encoder_memory(256, 256, 3)


@pytest.mark.parametrize("shape", [(100_000, 100_000), (40_000, 40_000, 3), (20_000, 20_000, 3)])
def test_encoder_refuses_huge_inputs_without_allocating_them(shape):
    huge = np.broadcast_to(np.float64(0.5), shape)  # a view: no memory behind it
    tracemalloc.start()
    start = time.perf_counter()
    with pytest.raises(ValueError, match=r"needs about .* MiB, above the limit"):
        bandelets.encode(huge, bpp=1.0)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 2**20 and time.perf_counter() - start < CASE_SECONDS
    assert encoder_memory(shape[0], shape[1], shape[2] if len(shape) == 3 else 1, container.TILE) > MAX_MEMORY


def test_encoder_memory_limit_is_overridable():
    x = np.random.default_rng(5).random((32, 32))
    with pytest.raises(ValueError, match="max_memory"):
        bandelets.encode(x, threshold=0.1, max_memory=encoder_memory(32, 32, 1) - 1)
    assert bandelets.encode(x, threshold=0.1, max_memory=encoder_memory(32, 32, 1))


def test_cli_refuses_a_hostile_file_in_one_line(tmp_path):
    path = tmp_path / "hostile.bdl"
    header = Header(
        height=16384,
        width=16384,
        channels=1,
        kind="image",
        transform="bandelet",
        wavelet="cdf97",
        levels=6,
        threshold=0.1,
    )
    path.write_bytes(pack(header, (b"\x00" * 20, b"\x00" * 20, b"\x00" * 20)))
    done = subprocess.run(
        [sys.executable, "-m", "bandelets", "decode", str(path), str(tmp_path / "out.npy")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "needs about" in done.stderr
    assert not (tmp_path / "out.npy").exists()
