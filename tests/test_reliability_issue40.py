"""Regressions of issue 40: a memory-safe loop filter, bounded work for tiled files, no traceback.

The decoder's compiled kernels have no bounds checks: :func:`test_the_kernels_stay_in_bounds_without_jit`
runs the decoder with ``NUMBA_DISABLE_JIT=1`` (plain Python, whose indexing checks every access) on
the golden files, hostile files and seeded mutations of the golden files. Run as a script
(``python tests/test_reliability_issue40.py FOLDER``), this file decodes the ``.bdl`` files of
``FOLDER`` and prints their outcomes as JSON: what that test runs in the subprocess.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import time
import zlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parent / "data"
SRC = str(Path(__file__).resolve().parents[1] / "src")
SMALL = {"max_side": 256, "max_samples": 2**16, "max_memory": 32 * 2**20, "max_work": 2**22}


def _decode_folder(folder: Path) -> dict[str, str]:
    """Decode every .bdl file of ``folder`` (the golden ones with the default limits, the others with
    :data:`SMALL`): ``decoded``, ``FormatError`` or what else was raised, by file name."""
    import warnings

    import bandelets
    from bandelets.format import container as tiling  # noqa: F811

    outcomes = {}
    for path in sorted(folder.glob("*.bdl")):
        data = path.read_bytes()
        limits = {} if path.name.startswith("golden-") else SMALL
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                out = bandelets.decode(data, **limits)
            except ValueError as err:
                outcomes[path.name] = type(err).__name__
                continue
            except Exception as err:  # what the test is there to find
                outcomes[path.name] = f"{type(err).__name__}: {err}"
                continue
        sizes = {k: v for k, v in limits.items() if k in ("max_side", "max_samples")}
        header = tiling.header_of(data, **sizes)
        right = out.shape[:2] == (header.height, header.width) and bool(np.all(np.isfinite(out)))
        outcomes[path.name] = "decoded" if right else f"wrong shape or values {out.shape}"
    return outcomes


if __name__ == "__main__":
    print(json.dumps(_decode_folder(Path(sys.argv[1]))))
    sys.exit(0)

import bandelets  # noqa: E402
from bandelets.apps import cli, cliopts  # noqa: E402
from bandelets.format import container as tiling  # noqa: E402
from bandelets.format.fields import MAX_THRESHOLD, MAX_WORK, MIN_THRESHOLD, FormatError  # noqa: E402
from bandelets.format.filter import LoopFilter, filter_taps  # noqa: E402
from bandelets.format.header import pack, unpack  # noqa: E402
from bandelets.io import files, tempfiles  # noqa: E402
from bandelets.restore import loopfilter  # noqa: E402
from bandelets.runtime import compilation  # noqa: E402
from bandelets.samples import crease_normal_map  # noqa: E402
from bandelets.surfaces.checks import check_genus0  # noqa: E402

GOLDEN = sorted(DATA.glob("*.bdl"))


def _crc(body: bytes) -> bytes:
    return bytes(body) + struct.pack("<I", zlib.crc32(body))


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_DISABLE_JIT"}
    env["PYTHONPATH"] = SRC + os.pathsep + env.get("PYTHONPATH", "")
    return env | extra


def _one_line(err: str) -> list[str]:
    """stderr's lines, numba's compile notice left out."""
    return [line for line in err.splitlines() if line.strip() and line.strip() != compilation.MESSAGE]


# ---------------------------------------------------------------------------------------------
# 1. Every index the compiled kernels compute from file data is in range.


def _wide_filter_file(side: int = 2, square: bool = False) -> bytes:
    """A ``side`` x ``side`` folded three-channel normal map with a radius-3 loop filter (the
    61-byte file of the issue: the filter reaches past more than one fold)."""
    x = crease_normal_map(8)[:side, :side]
    x[..., 2] *= -1  # three coded channels (local frames), which a folded map needs
    header, streams = unpack(
        bandelets.encode(x, threshold=0.05, kind="normal-map", restore=False, riesz=False, lifting=False)
    )
    cross = 2 if square else 0
    taps = filter_taps(3, cross, header.channels, square)
    wide = LoopFilter(radius=3, cross=cross, square=square, clip=0, shift=4, coefficients=(1,) * (3 * taps))
    return pack(replace(header, loop_filter=wide, folded=True), streams)


def test_across_folds_into_the_image_from_any_offset():
    across = loopfilter._across.py_func
    for rows in (1, 2, 3, 5):
        for i in range(-7, rows + 7):
            for j in range(-7, rows + 7):
                k, m = across(i, j, rows, rows)
                assert 0 <= k < rows and 0 <= m < rows, (i, j, rows)
    assert across(-3, 0, 2, 2) == (1, 0)  # was (2, 1): past the array
    # Within a side of the border, one fold as before (the bytes of ordinary files are unchanged).
    assert across(-1, 0, 4, 4) == (0, 3) and across(4, 5, 4, 4) == (0, 1)


@pytest.mark.parametrize("square", [False, True])
def test_a_filter_wider_than_a_folded_map_decodes_to_unit_vectors(square):
    data = _wide_filter_file(2, square)
    assert unpack(data)[0].folded and len(data) < 100
    out = bandelets.decode(data)
    assert out.shape == (2, 2, 3) and np.allclose(np.linalg.norm(out, axis=-1), 1.0)


def _mutations(count: int, seed: int = 40) -> dict[str, bytes]:
    """Seeded bit flips, byte sets and truncations of the golden files of one tile, behind a valid
    CRC (the stream lengths repaired as in test_hardening, so that the mutations reach the kernels)."""
    from test_hardening import _repaired

    rng = np.random.default_rng(seed)
    bodies = [p.read_bytes()[:-4] for p in GOLDEN if not p.stem.endswith("-tiled")]
    out = {}
    for n in range(count):
        body = bytearray(bodies[n % len(bodies)])
        kind = n % 3
        if kind == 0:  # bit flips
            for _ in range(int(rng.integers(1, 4))):
                bit = int(rng.integers(0, 8 * len(body)))
                body[bit // 8] ^= 1 << (bit % 8)
            data = _crc(body)
        elif kind == 1:  # byte sets anywhere, lengths repaired
            for _ in range(int(rng.integers(1, 4))):
                body[int(rng.integers(0, len(body)))] = int(rng.integers(0, 256))
            data = _repaired(body)
        else:  # truncations, lengths repaired
            data = _repaired(body[: int(rng.integers(1, len(body)))])
        out[f"mutation-{n:04d}.bdl"] = data
    return out


def test_the_kernels_stay_in_bounds_without_jit(tmp_path):
    """The golden files, the hostile files of this issue and 300 seeded mutations, decoded with
    ``NUMBA_DISABLE_JIT=1``: Python's indexing checks every index the kernels compute; only a
    ``FormatError`` or a finite array of the right shape may come out."""
    for path in GOLDEN:
        (tmp_path / f"golden-{path.name}").write_bytes(path.read_bytes())
    for square in (False, True):
        for side in (2, 4):
            (tmp_path / f"wide-{side}-{square}.bdl").write_bytes(_wide_filter_file(side, square))
    for name, data in _mutations(300).items():
        (tmp_path / name).write_bytes(data)
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, __file__, str(tmp_path)],
        capture_output=True,
        text=True,
        env=_env(NUMBA_DISABLE_JIT="1"),
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    outcomes = json.loads(run.stdout.splitlines()[-1])
    bad = {name: what for name, what in outcomes.items() if what not in ("decoded", "FormatError")}
    assert not bad, bad
    assert all(outcomes[f"golden-{p.name}"] == "decoded" for p in GOLDEN)
    assert all(outcomes[name] == "decoded" for name in outcomes if name.startswith("wide-"))
    kinds = [outcomes[name] for name in outcomes if name.startswith("mutation-")]
    assert len(kinds) == 300 and kinds.count("decoded") >= 15 and kinds.count("FormatError") > 100
    assert time.perf_counter() - start < 150


# ---------------------------------------------------------------------------------------------
# 2. Numeric options parsed with their bounds.


@pytest.mark.parametrize(
    "argv",
    [
        ["encode", "x.png", "x.bdl", "--max-memory", "inf"],
        ["encode", "x.png", "x.bdl", "--max-memory", "1e400"],
        ["encode", "x.png", "x.bdl", "--max-memory", "nan"],
        ["encode", "x.png", "x.bdl", "--max-memory", "-5"],
        ["encode", "x.png", "x.bdl", "--max-memory", "infG"],
        ["decode", "x.bdl", "x.png", "--max-memory", "1e400"],
        ["encode", "x.png", "x.bdl", "--bpp", "inf"],
        ["encode", "x.png", "x.bdl", "--bpp", "1e400"],
        ["encode", "x.png", "x.bdl", "--threshold", "nan"],
        ["encode", "x.png", "x.bdl", "--psnr", "-40"],
        ["encode", "x.png", "x.bdl", "--max-angle", "-inf"],
        ["encode", "x.png", "x.bdl", "--tile", "-16"],
        ["encode", "x.png", "x.bdl", "--tile", "1e3"],
        ["demo", "--size", "-1"],
        ["demo", "--size", "0", "--rates", "1"],
        ["demo", "--rates", "1,nan"],
        ["rd", "sample:crease", "--rates", "0.5,inf"],
        ["rd", "sample:crease", "--size", "-64"],
        ["mesh-encode", "x.obj", "x.bdl", "--size", "-2"],
        ["mesh-encode", "x.obj", "x.bdl", "--bpp", "nan"],
        ["mesh-encode", "x.obj", "x.bdl", "--bits-per-vertex", "1e400"],
        ["mesh-encode", "x.obj", "x.bdl", "--bytes", "-5"],
        ["mesh-encode", "x.obj", "x.bdl", "--bytes", "1e400"],
        ["mesh-encode", "x.obj", "x.bdl", "--normal-weight", "inf"],
        ["mesh-decode", "x.bdl", "x.obj", "--vertices", "0"],
        ["geometry-image", "x.obj", "--size", "-256"],
        ["batch", "x", "--out", "y", "--workers", "0"],
        ["batch", "x", "--out", "y", "--bpp", "nan"],
        ["batch", "x", "--out", "y", "--psnr", "inf"],
        ["batch", "x", "--out", "y", "--threshold", "-1"],
        ["batch", "x", "--out", "y", "--bits-per-vertex", "1e400"],
    ],
    ids=lambda argv: " ".join(argv[3:] if argv[0] in ("encode", "decode") else argv),
)
def test_hostile_numbers_are_one_line_and_exit_2(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status = cli.main(argv)
    lines = _one_line(capsys.readouterr().err)
    assert status == 2 and len(lines) == 1 and lines[0].startswith("bandelets: error:"), lines
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("extra", [[], ["--no-lossless"]])
def test_a_rate_target_far_above_any_file_is_met_by_the_best_file(extra, capsys, tmp_path):
    """``--bpp 1e300``: finite, so accepted; it made the lossless coder's byte budget overflow int64
    (a traceback from numba's typing)."""
    png = tmp_path / "in.png"
    png.write_bytes(_png_of(np.arange(256, dtype=np.uint8).reshape(16, 16)))
    assert cli.main(["encode", str(png), str(tmp_path / "o.bdl"), "--bpp", "1e300", "-q", *extra]) == 0
    assert bandelets.decode((tmp_path / "o.bdl").read_bytes()).shape == (16, 16)


def _png_of(pixels: np.ndarray) -> bytes:
    import imagecodecs

    return imagecodecs.png_encode(pixels)


def test_memory_sizes_keep_their_meaning():
    assert cliopts.memory_size("512") == 512 * 2**20
    assert cliopts.memory_size("4G") == 4 * 2**30 and cliopts.memory_size("1.5k") == 1536
    assert cliopts.memory_size("1048576G") == cliopts.MAX_MEMORY_BYTES
    assert cliopts.positive_float("1e-3") == 1e-3 and cliopts.natural_int("0") == 0
    assert cliopts.rate_list("0.25, 1,", "--rates") == [0.25, 1.0]


# ---------------------------------------------------------------------------------------------
# 3. Meshes with coordinates that are not finite.

_TETRAHEDRON = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 {z}\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n"


@pytest.mark.parametrize("z", ["nan", "inf", "-inf"])
def test_a_mesh_with_a_coordinate_that_is_not_finite_is_refused(z, tmp_path, capsys):
    mesh = tmp_path / "bad.obj"
    mesh.write_text(_TETRAHEDRON.format(z=z))
    status = cli.main(["mesh-encode", str(mesh), str(tmp_path / "bad.bdl")])
    lines = _one_line(capsys.readouterr().err)
    assert status == 2 and len(lines) == 1 and "finite" in lines[0], lines
    assert not (tmp_path / "bad.bdl").exists()
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, float(z)]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    with pytest.raises(ValueError, match="not finite"):
        check_genus0(vertices, faces)
    check_genus0(np.nan_to_num(vertices, posinf=1.0, neginf=1.0, nan=1.0), faces)  # the same, finite


# ---------------------------------------------------------------------------------------------
# 4. A fixed cost per tile.


def _tiny_tiles(side: int, tile: int = 16) -> bytes:
    one = bandelets.encode(crease_normal_map(tile), bpp=4.0, kind="normal-map", restore=False)
    grid = tiling.Grid(side, side, tile)
    return tiling.pack(grid, [one] * len(grid.boxes))


@pytest.mark.parametrize("side", [1024, 8192])  # 4,096 and 262,144 tiles of 16 x 16
def test_many_tiny_tiles_are_refused_at_once(side):
    data = _tiny_tiles(side)
    start = time.process_time()
    with pytest.raises(FormatError, match="max_work"):
        bandelets.decode(data)
    with pytest.raises(FormatError, match="max_work"):  # what `bandelets info` and `decode` read first
        tiling.header_of(data)
    assert time.process_time() - start < 1.0
    count = (side // 16) ** 2
    assert count * tiling.TILE_WORK > MAX_WORK
    out = bandelets.decode(data, region=(0, 0, 40, 40), max_work=count * tiling.TILE_WORK)
    assert out.shape == (40, 40, 3)  # a decoder given the work reads what it asks for


def test_a_file_of_as_many_tiles_as_the_work_allows_decodes():
    most = MAX_WORK // tiling.TILE_WORK  # 2,048
    data = _tiny_tiles(16 * int(np.sqrt(most // 2)))  # 1,024 tiles of 16
    start = time.process_time()
    assert bandelets.decode(data).shape[2] == 3
    assert time.process_time() - start < 4.0


def test_the_encoder_refuses_tiles_the_decoder_would_refuse():
    with pytest.raises(ValueError, match="choose larger tiles"):
        bandelets.encode(np.zeros((1024, 1024)), bpp=1.0, tile=16)


# ---------------------------------------------------------------------------------------------
# 5. No kernel compiled at decode time for what a file asks for.

_SIGNATURES = """
import struct, sys, warnings, zlib
from pathlib import Path
import numpy as np
from numba.core.registry import CPUDispatcher
import bandelets
from bandelets.samples import crease_normal_map

def signatures():
    return {f"{name}.{attr}": len(value.signatures) for name, module in list(sys.modules.items())
            if name.startswith("bandelets") for attr, value in list(vars(module).items())
            if isinstance(value, CPUDispatcher)}

bandelets.decode(bandelets.encode(crease_normal_map(32), bpp=1.0, kind="normal-map"))
golden = sorted(Path(sys.argv[1]).glob("*.bdl"))
for path in golden:
    bandelets.decode(path.read_bytes())
before, grown = signatures(), []
for path in golden:
    if path.stem.endswith("-tiled"):
        continue
    body = bytearray(path.read_bytes()[:-4])
    for threshold in [float(t) for t in sys.argv[2:]]:
        struct.pack_into("<f", body, 10, threshold)  # the header's float32 threshold
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                bandelets.decode(bytes(body) + struct.pack("<I", zlib.crc32(body)))
            except ValueError:
                pass
        after = signatures()
        grown += [f"{path.name} at {threshold:g}: {k}" for k in after if after[k] != before.get(k, 0)]
        before = after
print(grown)
"""


def test_a_hostile_threshold_compiles_no_kernel_at_decode_time():
    """After an ordinary encode and the decode of every golden file, the golden files at extreme
    thresholds (float64 restoration, float64 Riesz turns) add no specialization to any kernel."""
    thresholds = [MIN_THRESHOLD, 1e-30, 1e-5, 2.0**-10, 1e10, 1e30, MAX_THRESHOLD]
    run = subprocess.run(
        [sys.executable, "-c", _SIGNATURES, str(DATA), *map(str, thresholds)],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=900,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    assert run.stdout.strip() == "[]", run.stdout


# ---------------------------------------------------------------------------------------------
# 6. libpng's warnings before our one line.


def _chunk(kind: bytes, data: bytes, crc: int | None = None) -> bytes:
    crc = zlib.crc32(kind + data) if crc is None else crc
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)


def _png(ihdr: bytes, *chunks: bytes) -> bytes:
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + b"".join(chunks) + _chunk(b"IEND", b"")


@pytest.mark.parametrize(
    "ihdr",
    [
        struct.pack(">IIBBBBB", 0, 0, 8, 0, 0, 0, 0),  # zero size: two "PNG warning:" lines before
        struct.pack(">IIBBBBB", 4, 4, 8, 0, 0, 0, 7),  # an unknown interlace method: libpng warns, fails
    ],
    ids=["zero-size", "bad-interlace"],
)
def test_a_corrupt_png_is_one_line_on_stderr(ihdr, tmp_path):
    (tmp_path / "bad.png").write_bytes(_png(ihdr))
    run = subprocess.run(
        [sys.executable, "-m", "bandelets", "encode", "bad.png", "bad.bdl"],
        capture_output=True,
        text=True,
        env=_env(),
        cwd=tmp_path,
        timeout=300,
    )
    lines = _one_line(run.stderr)
    assert run.returncode == 2 and len(lines) == 1, run.stderr
    assert lines[0].startswith("bandelets: error: bad.png: not a readable PNG file")


def test_a_warning_about_a_png_that_reads_is_still_shown(tmp_path):
    pixels = zlib.compress(b"\x00\x01\x02\x03\x04" * 4)  # 4 rows: filter byte and 4 samples
    text = _chunk(b"tEXt", b"a\x00b", crc=1)  # a bad CRC in an ancillary chunk: libpng warns, reads on
    (tmp_path / "ok.png").write_bytes(
        _png(struct.pack(">IIBBBBB", 4, 4, 8, 0, 0, 0, 0), text, _chunk(b"IDAT", pixels))
    )
    code = "from bandelets.io.files import read_array; print(read_array('ok.png', 'image')[0].shape)"
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=_env(), cwd=tmp_path, timeout=300
    )
    assert run.returncode == 0 and run.stdout.strip() == "(4, 4)", run.stderr
    assert "PNG warning" in run.stderr


# ---------------------------------------------------------------------------------------------
# 7. Temporary files of an interrupted write.


def test_write_atomic_names_its_temporary_file_as_ours(tmp_path):
    seen = []

    def write(tmp: str) -> None:
        seen.append(Path(tmp))
        Path(tmp).write_bytes(b"data")

    files.write_atomic(tmp_path / "out.bdl", write)
    assert (tmp_path / "out.bdl").read_bytes() == b"data"
    assert seen[0].parent == tmp_path and tempfiles.is_ours(seen[0].name), seen
    assert seen[0].name.startswith(".out.bdl.") and not seen[0].exists()


def test_a_write_killed_midway_leaves_a_file_the_next_write_removes_once_stale(tmp_path):
    code = (
        "import os, signal; from bandelets.io.files import write_atomic\n"
        "write_atomic('out.bdl', lambda tmp: os.kill(os.getpid(), signal.SIGKILL))\n"
    )
    run = subprocess.run([sys.executable, "-c", code], env=_env(), cwd=tmp_path, timeout=300)
    assert run.returncode == -9
    (left,) = [p for p in tmp_path.iterdir()]
    assert tempfiles.is_ours(left.name) and not (tmp_path / "out.bdl").exists()
    # Others' files, and ours of less than an hour, are kept.
    old = time.time() - 2 * tempfiles.STALE_SECONDS
    keep = [
        tmp_path / ".out.bdl.abcd1234.tmp",
        tmp_path / "out.bdl.abcd1234.bandelets-tmp",
        tmp_path / "x.bdl",
    ]
    for path in keep:
        path.write_bytes(b"theirs")
        os.utime(path, (old, old))
    (tmp_path / ".x.bdl.link1234.bandelets-tmp").symlink_to(tmp_path / "x.bdl")
    recent = tmp_path / ".y.bdl.qwerty12.bandelets-tmp"
    recent.write_bytes(b"a write in progress")
    files.write_atomic(tmp_path / "other.bdl", b"data")
    assert left.exists()  # not an hour old yet
    os.utime(left, (old, old))
    assert tempfiles.remove_stale(tmp_path, force=True) == [left.name]
    assert not left.exists() and recent.exists() and all(path.exists() for path in keep)
    assert (tmp_path / ".x.bdl.link1234.bandelets-tmp").is_symlink()
