"""The command line (bandelets.apps.cli), run in-process except for the start-up checks."""

from __future__ import annotations

import json
import os
import resource
import shutil
import struct
import subprocess
import sys
import time
import warnings
import zlib
from dataclasses import replace
from pathlib import Path

import imagecodecs
import numpy as np
import pytest
from conftest import straight_edge

import bandelets
from bandelets.apps import cli, show
from bandelets.apps.cli import main
from bandelets.codec import decoder
from bandelets.format.header import pack, unpack
from bandelets.format.samples import from_samples, to_samples
from bandelets.io import files
from bandelets.io.files import SUFFIXES
from bandelets.io.floatformats import read_exr, read_tiff, write_exr, write_tiff
from bandelets.metrics import angular_error, psnr
from bandelets.runtime import compilation
from bandelets.samples import crease_normal_map
from bandelets.surfaces.codec import MESH_FORMATS


def _gray(shape=(40, 56)) -> np.ndarray:
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]] / max(shape)
    return np.clip(0.5 + 0.35 * straight_edge(shape=shape) + 0.1 * x - 0.05 * y, 0, 1)


def _write_png(path: Path, pixels: np.ndarray) -> Path:
    path.write_bytes(imagecodecs.png_encode(pixels))
    return path


def _read_png(path: Path) -> np.ndarray:
    return imagecodecs.png_decode(path.read_bytes())


def _run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    # The notice of numba's first compilation (in whichever test first compiles a kernel) is not
    # part of what the command says.
    err = "".join(line for line in err.splitlines(keepends=True) if line.rstrip("\n") != compilation.MESSAGE)
    return status, out, err


def _ok(capsys, *argv) -> str:
    status, out, err = _run(capsys, *argv)
    assert status == 0, err
    assert "error" not in err
    return out


@pytest.fixture
def gray_png(tmp_path) -> tuple[Path, np.ndarray]:
    values = _gray()
    return _write_png(tmp_path / "gray.png", np.rint(values * 255).astype(np.uint8)), values


@pytest.fixture
def npy(tmp_path) -> tuple[Path, np.ndarray]:
    values = _gray((32, 48)) * 4.0 - 1.0
    path = tmp_path / "values.npy"
    np.save(path, values)
    return path, values


# ---------------------------------------------------------------------------------------------
# Round trips.


def test_gray_png_encode_info_decode(tmp_path, capsys, gray_png):
    png, values = gray_png
    bdl = tmp_path / "gray.bdl"
    assert _ok(capsys, "encode", png, bdl, "--psnr", "34") == ""
    info = json.loads(_ok(capsys, "info", bdl))
    assert info["bytes"] == bdl.stat().st_size
    assert (info["width"], info["height"], info["channels"]) == (56, 40, 1)
    assert info["kind"] == "image"
    assert info["transform"] == "bandelet"
    assert info["bpp"] == pytest.approx(8 * info["bytes"] / (40 * 56))
    out = tmp_path / "decoded.png"
    assert _ok(capsys, "decode", bdl, out) == ""
    decoded = _read_png(out)
    assert decoded.dtype == np.uint8
    assert decoded.shape == (40, 56)
    assert psnr(values, decoded / 255.0) >= 33.5  # 34 dB, less the 8-bit rounding


def test_default_target_is_one_bpp(tmp_path, capsys, gray_png):
    png, _ = gray_png
    bdl = tmp_path / "gray.bdl"
    _ok(capsys, "encode", png, bdl)
    target = 40 * 56 / 8
    assert 0.97 * target <= bdl.stat().st_size <= target


def test_info_json(tmp_path, capsys, npy):
    path, _ = npy
    bdl = tmp_path / "v.bdl"
    _ok(capsys, "encode", path, bdl, "--threshold", "0.02", "--transform", "wavelet", "--wavelet", "db4")
    out = _ok(capsys, "info", bdl)
    assert out.count("\n") == 1  # one JSON object on one line
    info = json.loads(out)
    keys = ("width", "height", "channels", "kind", "transform", "threshold", "bytes", "bpp", "bits")
    for key in keys:
        assert key in info
    for key in ("quadtree", "geometry", "coefficients"):
        assert key in info["bits"]
    assert info["bytes"] == bdl.stat().st_size
    assert info["transform"] == "wavelet"
    assert info["threshold"] == float(np.float32(0.02))  # a float32 on disk (format version 17)
    assert sum(info["bits"].values()) == 8 * info["bytes"]
    assert info["bits"]["coefficients"] > 0


def test_info_names_the_local_frames_of_a_normal_map(tmp_path, capsys):
    """A normal map facing every way is coded in local frames; ``info`` says so."""
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(32, 32, 3)) + [0.0, 0.0, 2.0]
    normals[:, :8, 2] *= -1
    path, bdl = tmp_path / "n.npy", tmp_path / "n.bdl"
    np.save(path, normals / np.linalg.norm(normals, axis=-1, keepdims=True))
    _ok(capsys, "encode", path, bdl, "--kind", "normal-map", "--bpp", "2")
    info = json.loads(_ok(capsys, "info", bdl))
    assert (info["channels"], info["frames"], info["normal_weight"]) == (3, True, 0.35)
    assert "extension" not in info
    assert info["folded"] is False  # not an octahedral geometry image (bandelets.codec.normalmaps.octahedral)


def test_16_bit_rgb_normal_map(tmp_path, capsys, crease_map):
    pixels = np.rint((crease_map[:48, :40] + 1) / 2 * 65535).astype(np.uint16)
    png = _write_png(tmp_path / "normals.png", pixels)
    bdl = tmp_path / "normals.bdl"
    _ok(capsys, "encode", png, bdl, "--kind", "normal-map", "--bpp", "2")
    assert json.loads(_ok(capsys, "info", bdl))["kind"] == "normal-map"
    out = tmp_path / "normals-decoded.png"
    _ok(capsys, "decode", bdl, out)
    decoded = _read_png(out)
    assert decoded.dtype == np.uint16
    assert decoded.shape == pixels.shape
    vectors = decoded / 65535 * 2 - 1
    assert psnr(crease_map[:48, :40], vectors, "normal-map") > 25


def test_no_restore_keeps_the_size_and_turns_the_restoration_off(tmp_path, capsys, crease_map):
    npy = tmp_path / "normals.npy"
    np.save(npy, crease_map)
    sizes = {}
    for flags in ((), ("--no-restore",)):
        bdl = tmp_path / f"normals{len(flags)}.bdl"
        # The restoration costs no bits (the loop filter does: left out here). The channels are
        # pinned: a restored rate target may also try their Riesz pair and keep the better file.
        _ok(
            capsys,
            "encode",
            npy,
            bdl,
            "--kind",
            "normal-map",
            "--bpp",
            "1",
            "--no-loop-filter",
            "--no-riesz",
            *flags,
        )
        info = json.loads(_ok(capsys, "info", bdl))
        sizes[flags] = info["bytes"]
        assert (info["restoration"] > 0) == (not flags)
        assert info["loop_filter"] is None
    assert len(set(sizes.values())) == 1


def test_decode_no_restore_is_plain_dequantization(tmp_path, capsys, crease_map):
    npy, bdl = tmp_path / "normals.npy", tmp_path / "normals.bdl"
    np.save(npy, crease_map)
    _ok(capsys, "encode", npy, bdl, "--kind", "normal-map", "--bpp", "1")
    data = bdl.read_bytes()
    header, streams = unpack(data)
    assert header.restoration > 0
    outputs = {}
    for flags in ((), ("--no-restore",)):
        out = tmp_path / f"decoded{len(flags)}.npy"
        _ok(capsys, "decode", bdl, out, *flags)
        outputs[flags] = np.load(out)
    plain = bandelets.decode(pack(replace(header, restoration=0, loop_filter=None), streams))
    np.testing.assert_array_equal(outputs[("--no-restore",)], plain.astype(np.float32))
    np.testing.assert_array_equal(bandelets.decode(data, restore=False), plain)
    assert psnr(crease_map, outputs[()], "normal-map") > psnr(crease_map, plain, "normal-map")
    assert bdl.read_bytes() == data  # the input is never touched


def test_rgba_png_drops_alpha_with_a_warning(tmp_path, capsys):
    rgb = np.rint(np.stack([_gray((32, 32))] * 3, -1) * 255).astype(np.uint8)
    alpha = np.full((32, 32, 1), 200, np.uint8)
    png = _write_png(tmp_path / "rgba.png", np.concatenate([rgb, alpha], -1))
    bdl = tmp_path / "rgba.bdl"
    status, _, err = _run(capsys, "encode", png, bdl, "--threshold", "0.01", "-q")  # -q: no summary
    assert status == 0
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("bandelets: warning:")
    assert "alpha" in lines[0]
    assert json.loads(_ok(capsys, "info", bdl))["channels"] == 3
    out = tmp_path / "rgba.npy"
    _ok(capsys, "decode", bdl, out)
    decoded = np.load(out)
    assert decoded.shape == (32, 32, 3)
    assert np.max(np.abs(decoded - rgb / 255)) < 0.05


def test_npy_in_npy_out(tmp_path, capsys, npy):
    path, values = npy
    bdl = tmp_path / "v.bdl"
    _ok(capsys, "encode", path, bdl, "--threshold", "0.01")
    out = tmp_path / "out.npy"
    _ok(capsys, "decode", bdl, out)
    decoded = np.load(out)
    assert decoded.dtype == np.float32
    assert decoded.shape == values.shape
    assert np.sqrt(np.mean((decoded - values) ** 2)) < 0.01


def test_npy_to_png_uses_16_bits(tmp_path, capsys, npy):
    path, values = npy
    bdl = tmp_path / "v.bdl"
    _ok(capsys, "encode", path, bdl, "--threshold", "0.01")
    out = tmp_path / "out.png"
    _ok(capsys, "decode", bdl, out)
    decoded = _read_png(out)
    assert decoded.dtype == np.uint16
    assert decoded.shape == values.shape


def test_long_wavelets_give_no_spurious_warning(tmp_path, capsys, npy):
    path, _ = npy
    status, _, err = _run(
        capsys, "encode", path, tmp_path / "o.bdl", "--wavelet", "db8", "--threshold", "0.05", "-q"
    )
    assert status == 0
    assert err == ""


def test_force_overwrites(tmp_path, capsys, npy):
    path, _ = npy
    bdl = tmp_path / "v.bdl"
    bdl.write_bytes(b"old")
    status, _, err = _run(capsys, "encode", path, bdl)
    assert status == 2 and "--force" in err
    assert bdl.read_bytes() == b"old"
    _ok(capsys, "encode", path, bdl, "--force")
    assert bdl.read_bytes()[:4] == b"BDL\x1a"
    out = tmp_path / "out.npy"
    out.write_bytes(b"old")
    _ok(capsys, "decode", bdl, out, "-f")
    assert np.load(out).shape == (32, 48)


# ---------------------------------------------------------------------------------------------
# Errors: exit status 2, one line, no traceback, nothing left behind.


def _expect_error(capsys, folder: Path, *argv) -> str:
    before = sorted(p.name for p in folder.iterdir())
    status, out, err = _run(capsys, *argv)
    assert status == 2, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("bandelets: error:")
    assert "Traceback" not in err
    assert out == ""
    assert sorted(p.name for p in folder.iterdir()) == before, "a file was left behind"
    return lines[0]


@pytest.fixture
def valid_bdl(tmp_path, capsys, npy) -> Path:
    path, _ = npy
    bdl = tmp_path / "valid.bdl"
    _ok(capsys, "encode", path, bdl, "--threshold", "0.05")
    return bdl


def test_missing_input(tmp_path, capsys):
    line = _expect_error(capsys, tmp_path, "encode", tmp_path / "nothing.png", tmp_path / "o.bdl")
    assert "nothing.png" in line


def test_unreadable_png(tmp_path, capsys):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"this is not a PNG file at all" * 4)
    _expect_error(capsys, tmp_path, "encode", bad, tmp_path / "o.bdl")


def test_unsupported_suffix(tmp_path, capsys):
    tif = tmp_path / "image.tif"
    tif.write_bytes(b"II*\x00")
    line = _expect_error(capsys, tmp_path, "encode", tif, tmp_path / "o.bdl")
    assert ".tif" in line


def test_unsupported_output_suffix(tmp_path, capsys, valid_bdl):
    _expect_error(capsys, tmp_path, "decode", valid_bdl, tmp_path / "out.jpg")


@pytest.mark.parametrize(
    ("array", "words"),
    [
        (np.full((8, 8), np.nan), "NaN"),
        (np.zeros((0, 0)), "small"),
        (np.zeros(0), "shape"),
        (np.array([["a", "b"]]), "numeric"),
    ],
)
def test_bad_npy(tmp_path, capsys, array, words):
    path = tmp_path / "bad.npy"
    np.save(path, array)
    line = _expect_error(capsys, tmp_path, "encode", path, tmp_path / "o.bdl")
    assert words in line


def test_output_exists_without_force(tmp_path, capsys, npy, valid_bdl):
    path, _ = npy
    before = valid_bdl.read_bytes()
    line = _expect_error(capsys, tmp_path, "encode", path, valid_bdl, "--threshold", "0.01")
    assert "exists" in line
    assert valid_bdl.read_bytes() == before


def test_output_same_as_input(tmp_path, capsys, npy, valid_bdl):
    path, _ = npy
    before = path.read_bytes()
    for extra in ([], ["--force"]):
        line = _expect_error(capsys, tmp_path, "encode", path, path, *extra)
        assert "input" in line
        assert path.read_bytes() == before
    _expect_error(capsys, tmp_path, "decode", valid_bdl, valid_bdl, "--force")
    assert valid_bdl.read_bytes()[:4] == b"BDL\x1a"


def test_output_folder_missing(tmp_path, capsys, npy):
    path, _ = npy
    _expect_error(capsys, tmp_path, "encode", path, tmp_path / "no" / "such" / "o.bdl")


@pytest.mark.parametrize("command", ["decode", "info"])
def test_corrupt_bdl(tmp_path, capsys, valid_bdl, command):
    corrupt = tmp_path / "corrupt.bdl"
    data = bytearray(valid_bdl.read_bytes())
    data[len(data) // 2] ^= 0xFF
    corrupt.write_bytes(bytes(data))
    not_bdl = tmp_path / "png.bdl"
    not_bdl.write_bytes(imagecodecs.png_encode(np.zeros((4, 4), np.uint8)))
    for path in (corrupt, not_bdl):
        args = [command, path] + ([tmp_path / "out.npy"] if command == "decode" else [])
        _expect_error(capsys, tmp_path, *args)


@pytest.mark.parametrize("command", ["decode", "info"])
def test_truncated_bdl(tmp_path, capsys, valid_bdl, command):
    data = valid_bdl.read_bytes()
    for n in (0, 10, 44, len(data) - 1):
        truncated = tmp_path / f"truncated-{n}.bdl"
        truncated.write_bytes(data[:n])
        args = [command, truncated] + ([tmp_path / "out.npy"] if command == "decode" else [])
        _expect_error(capsys, tmp_path, *args)


def test_normal_map_label_on_a_gray_file(tmp_path, capsys, valid_bdl):
    body = bytearray(valid_bdl.read_bytes()[:-4])
    body[5] = 1  # kind: normal-map
    relabelled = tmp_path / "relabelled.bdl"
    relabelled.write_bytes(bytes(body) + struct.pack("<I", zlib.crc32(bytes(body))))
    _expect_error(capsys, tmp_path, "decode", relabelled, tmp_path / "o.npy")


def test_missing_bdl(tmp_path, capsys):
    _expect_error(capsys, tmp_path, "info", tmp_path / "none.bdl")
    _expect_error(capsys, tmp_path, "decode", tmp_path / "none.bdl", tmp_path / "o.npy")


@pytest.mark.parametrize("bpp", ["0.0001", "0.01"])
def test_unreachable_bpp(tmp_path, capsys, npy, bpp):
    path, _ = npy
    line = _expect_error(capsys, tmp_path, "encode", path, tmp_path / "o.bdl", "--bpp", bpp)
    if bpp == "0.01":  # (0.0001 gives 'math domain error': see test_codec)
        assert "cannot be reached" in line


@pytest.mark.parametrize(
    "argv",
    [
        ["encode", "{npy}", "{out}", "--transform", "foo"],
        ["encode", "{npy}", "{out}", "--kind", "depth"],
        ["encode", "{npy}", "{out}", "--bpp", "lots"],
        ["encode", "{npy}", "{out}", "--bpp", "1", "--psnr", "30"],
        ["encode", "{npy}"],
        ["encode", "{npy}", "{out}", "--wavelet", "sym5"],
        ["encode", "{npy}", "{out}", "--kind", "normal-map"],  # one channel
        ["encode", "{npy}", "{out}", "--bpp", "-1"],
        ["frobnicate"],
        [],
        ["demo", "--size", "8", "--out", "{dir}/demo"],
    ],
)
def test_usage_errors(tmp_path, capsys, npy, argv):
    path, _ = npy
    argv = [a.format(npy=path, out=tmp_path / "o.bdl", dir=tmp_path) for a in argv]
    _expect_error(capsys, tmp_path, *argv)


# ---------------------------------------------------------------------------------------------
# Start-up.


def test_python_m_bandelets_help():
    done = subprocess.run(
        [sys.executable, "-m", "bandelets", "--help"], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0
    for command in ("encode", "decode", "info", "demo"):
        assert command in done.stdout
    assert done.stderr == ""


def test_bandelets_script_help_is_fast():
    script = shutil.which("bandelets")
    if script is None:
        pytest.skip("the bandelets script is not on PATH")
    env = dict(os.environ)
    subprocess.run([script, "--help"], capture_output=True, timeout=60, env=env)  # warm the caches
    start = time.perf_counter()
    done = subprocess.run([script, "--help"], capture_output=True, text=True, timeout=60, env=env)
    elapsed = time.perf_counter() - start
    assert done.returncode == 0
    assert "usage: bandelets" in done.stdout
    assert elapsed < 0.5, f"bandelets --help took {elapsed:.2f} s"


def test_the_command_line_takes_the_formats_choices_without_loading_the_codec():
    code = "import sys, bandelets.apps.cli; print(sorted({'numba', 'numpy'} & set(sys.modules)))"
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert done.stdout.strip() == "[]"


def test_the_command_line_knows_the_file_formats():
    assert set(cli.IMAGE_SUFFIXES) == set(SUFFIXES) | {".jpg", ".jpeg", ".webp"}
    assert MESH_FORMATS == ("obj", "ply", "off")  # as _mesh_decode checks them


def _cpu_seconds(argv: list[str]) -> tuple[float, subprocess.CompletedProcess]:
    """CPU time (user + system) of ``python -m bandelets ARGV``: what the command costs, whatever
    the load of the machine does to its wall time."""

    env = dict(os.environ, PYTHONPATH=str(Path(bandelets.__file__).parents[1]))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(
        [sys.executable, "-m", "bandelets", *argv], capture_output=True, text=True, timeout=60, env=env
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), done


@pytest.mark.parametrize(
    ("argv", "limit"),
    [
        (["--help"], 0.3),
        (["decode", "missing.bdl", "out.png"], 0.5),
        (["encode", "missing.png", "out.bdl"], 0.5),
        (["encode", "--bpp", "x", "a.png", "b.bdl"], 0.5),
        (["show", "missing.bdl", "out.png"], 0.5),
        (["mesh-encode", "missing.off", "out.bdl"], 0.5),
    ],
)
def test_help_and_argument_errors_cost_little(tmp_path, argv, limit):
    _cpu_seconds(argv)  # warm the caches
    seconds, done = _cpu_seconds([str(tmp_path / a) if "." in a else a for a in argv])
    assert done.returncode == (0 if argv == ["--help"] else 2), done.stderr
    assert seconds < limit, f"bandelets {' '.join(argv)} took {seconds:.2f} s of CPU"


# ---------------------------------------------------------------------------------------------
# Summary lines, formats, normal maps.


def _normal_png(tmp_path: Path, lengths: float = 1.0) -> tuple[Path, np.ndarray]:

    pixels = to_samples(crease_normal_map(64) * lengths, "normal-map", 8)
    return _write_png(tmp_path / "normals.png", pixels), from_samples(pixels, "normal-map", 8)


def _numbers_of(line: str, after: str) -> float:
    return float(line.split(after, 1)[1].split()[0].rstrip(","))


def test_encode_prints_a_summary_measured_on_what_decode_writes(tmp_path, capsys):
    png, values = _normal_png(tmp_path)
    bdl, out = tmp_path / "n.bdl", tmp_path / "back.png"
    status, _, err = _run(capsys, "encode", png, bdl, "--kind", "normal-map", "--bpp", "2")
    assert status == 0
    (line,) = err.splitlines()
    assert line.startswith(f"{png} (64 x 64 x 3, 8-bit) -> {bdl}: {bdl.stat().st_size} bytes, ")
    assert _numbers_of(line, "bytes, ") == pytest.approx(8 * bdl.stat().st_size / 64**2, abs=1e-3)
    status, _, err = _run(capsys, "decode", bdl, out)
    assert status == 0 and err.startswith(f"{bdl} -> {out}: 64 x 64 x 3, 8-bit, ") and err.endswith(" s\n")
    decoded = _read_png(out).astype(float) / 255 * 2 - 1
    assert _numbers_of(line, "PSNR ") == pytest.approx(psnr(values, decoded, "normal-map"), abs=0.005)
    error = angular_error(values, decoded)
    assert _numbers_of(line, "angle mean ") == pytest.approx(error.mean, abs=0.005)
    assert _numbers_of(line, " p99 ") == pytest.approx(error.p99, abs=0.005)
    assert "lengths" not in line  # an 8-bit map of unit vectors
    assert _run(capsys, "encode", png, tmp_path / "q.bdl", "--kind", "normal-map", "-q")[2] == ""
    assert _run(capsys, "decode", bdl, tmp_path / "q.png", "-q")[2] == ""


def test_summary_names_vector_lengths_far_from_one(tmp_path, capsys):
    png, values = _normal_png(tmp_path, lengths=0.8)
    _, _, err = _run(capsys, "encode", png, tmp_path / "n.bdl", "--kind", "normal-map")
    lengths = np.linalg.norm(values, axis=-1)
    assert f"input vector lengths {lengths.min():.2f} to {lengths.max():.2f} (renormalised" in err


def test_psnr_and_max_angle_targets_hold_on_the_8_bit_decode(tmp_path, capsys):
    png, values = _normal_png(tmp_path)
    for option, target in (("--psnr", 35.0), ("--max-angle", 3.0)):
        bdl, out = tmp_path / "n.bdl", tmp_path / "n.png"
        _ok(capsys, "encode", png, bdl, "--kind", "normal-map", option, target, "-f", "-q")
        _ok(capsys, "decode", bdl, out, "-f", "-q")
        decoded = _read_png(out).astype(float) / 255 * 2 - 1
        if option == "--psnr":
            assert psnr(values, decoded, "normal-map") >= target
        else:
            assert 0.8 * target < angular_error(values, decoded).p99 <= target


@pytest.mark.parametrize(
    ("suffix", "dtype"),
    [(".tif", np.uint8), (".tiff", np.uint16), (".tif", np.float32), (".exr", np.float32)],
)
def test_tiff_and_exr_round_trips_keep_depth_and_type(tmp_path, capsys, suffix, dtype):

    normals = crease_normal_map(32)
    source = tmp_path / f"n{suffix}"
    if suffix == ".exr":
        write_exr(str(source), normals)
    else:
        floats = dtype == np.float32
        source.write_bytes(
            write_tiff(
                normals.astype(dtype)
                if floats
                else to_samples(normals, "normal-map", 8 * np.dtype(dtype).itemsize)
            )
        )
    bdl, out = tmp_path / "n.bdl", tmp_path / f"back{suffix}"
    _ok(capsys, "encode", source, bdl, "--kind", "normal-map", "--bpp", "3", "-q")
    depth = unpack(bdl.read_bytes())[0].depth
    assert depth == (0 if dtype == np.float32 else 8 * np.dtype(dtype).itemsize)
    _ok(capsys, "decode", bdl, out, "-q")
    back = read_exr(out) if suffix == ".exr" else read_tiff(out)[0]
    assert back.dtype == dtype and back.shape == (32, 32, 3)
    decoded = back if dtype == np.float32 else back / np.iinfo(dtype).max * 2 - 1
    assert angular_error(normals, decoded).mean < 2


def test_lossy_inputs_and_wrong_output_names_are_refused_before_any_work(tmp_path, capsys, monkeypatch):
    png, _ = _normal_png(tmp_path)
    jpeg = tmp_path / "n.jpg"
    jpeg.write_bytes(b"\xff\xd8\xff")
    status, _, err = _run(capsys, "encode", jpeg, tmp_path / "n.bdl")
    assert status == 2 and "JPEG inputs are refused" in err
    status, _, err = _run(capsys, "encode", png, tmp_path / "b.png")
    assert status == 2 and "name it b.bdl" in err and not (tmp_path / "b.png").exists()
    bdl = tmp_path / "n.bdl"
    _ok(capsys, "encode", png, bdl, "--kind", "normal-map", "-q")

    def no_decoding(*args, **kwargs):
        raise AssertionError("decoded before checking the output")

    monkeypatch.setattr(decoder, "decode_parsed", no_decoding)
    monkeypatch.setattr(decoder, "decode", no_decoding)
    monkeypatch.setattr(show, "geometry_figure", no_decoding)
    for command, output, words in (
        ("decode", "out.jpg", "unsupported output format .jpg"),
        ("show", "o.jpg", "name it o.png"),
    ):
        status, _, err = _run(capsys, command, bdl, tmp_path / output)
        assert status == 2 and words in err and not (tmp_path / output).exists()
    assert "OpenEXR" in subprocess.run(
        [sys.executable, "-m", "bandelets", "encode", "--help"], capture_output=True, text=True, timeout=60
    ).stdout.replace("\n", " ")


def test_max_memory_option(tmp_path, capsys):
    png, _ = _normal_png(tmp_path)
    bdl = tmp_path / "n.bdl"
    status, _, err = _run(capsys, "encode", png, bdl, "--max-memory", "1M")
    assert status == 2 and "above the limit of 1 MiB" in err and not bdl.exists()
    _ok(capsys, "encode", png, bdl, "--max-memory", "1G", "-q")
    status, _, err = _run(capsys, "decode", bdl, tmp_path / "o.png", "--max-memory", "0.5")
    assert status == 2 and "above the limit of 0 MiB" in err
    status, _, err = _run(capsys, "decode", bdl, tmp_path / "o.png", "--max-memory", "lots")
    assert status == 2 and "512M or 4G" in err


def test_xy_normal_maps_decode_to_their_layout(tmp_path, capsys):

    normals = crease_normal_map(32)
    two = tmp_path / "xy.npy"
    np.save(two, normals[..., :2])
    _ok(capsys, "encode", two, tmp_path / "xy.bdl", "--kind", "normal-map", "-q")
    assert json.loads(_ok(capsys, "info", tmp_path / "xy.bdl"))["layout"] == "xy"
    _ok(capsys, "decode", tmp_path / "xy.bdl", tmp_path / "xy-back.npy", "-q")
    assert np.load(tmp_path / "xy-back.npy").shape == (32, 32, 2)
    # RGB with ambient occlusion in blue, as BC5-style maps are shipped.
    pixels = np.rint((normals + 1) / 2 * 255).astype(np.uint8)
    pixels[..., 2] = 77
    png = _write_png(tmp_path / "rg.png", pixels)
    _ok(capsys, "encode", png, tmp_path / "rg.bdl", "--kind", "normal-map", "--xy", "--bpp", "3", "-q")
    _ok(capsys, "decode", tmp_path / "rg.bdl", tmp_path / "rg-back.png", "-q")
    back = _read_png(tmp_path / "rg-back.png").astype(float) / 255 * 2 - 1
    assert back.shape == (32, 32, 3)
    assert angular_error(normals, back).mean < 1.5
    status, _, err = _run(capsys, "encode", png, tmp_path / "x.bdl", "--xy")
    assert status == 2 and "normal maps only" in err


def test_integer_npy_normal_maps_are_samples(tmp_path, capsys):

    normals = crease_normal_map(32)
    np.save(tmp_path / "u8.npy", np.rint((normals + 1) / 2 * 255).astype(np.uint8))
    _ok(
        capsys, "encode", tmp_path / "u8.npy", tmp_path / "u8.bdl", "--kind", "normal-map", "--bpp", "3", "-q"
    )
    decoded = bandelets.decode((tmp_path / "u8.bdl").read_bytes())
    assert angular_error(normals, decoded).mean < 1.5
    np.save(tmp_path / "i32.npy", np.zeros((8, 8, 3), np.int32))
    status, _, err = _run(capsys, "encode", tmp_path / "i32.npy", tmp_path / "i.bdl", "--kind", "normal-map")
    assert status == 2 and "int32 values has no agreed scale" in err


def test_library_warnings_are_not_ours_to_show(tmp_path, capsys, monkeypatch, npy):

    read = files.read_array

    def noisy(*args):
        warnings.warn_explicit(
            "The TBB threading layer requires TBB", UserWarning, "numba/np/ufunc/parallel.py", 1
        )
        return read(*args)

    monkeypatch.setattr(files, "read_array", noisy)
    status, _, err = _run(capsys, "encode", npy[0], tmp_path / "o.bdl", "-q")
    assert status == 0 and err == ""
