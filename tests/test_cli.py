"""The command line (bandelets.cli), run in-process except for the start-up checks."""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
import time
import zlib
from dataclasses import replace
from pathlib import Path

import imagecodecs
import numpy as np
import pytest
from conftest import straight_edge

import bandelets
from bandelets.bitstream import pack, unpack
from bandelets.cli import main
from bandelets.metrics import psnr


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
    assert info["threshold"] == 0.02
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
        _ok(capsys, "encode", npy, bdl, "--kind", "normal-map", "--bpp", "1", *flags)
        info = json.loads(_ok(capsys, "info", bdl))
        sizes[flags] = info["bytes"]
        assert (info["restoration"] > 0) == (not flags)
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
    plain = bandelets.decode(pack(replace(header, restoration=0), streams))
    np.testing.assert_array_equal(outputs[("--no-restore",)], plain.astype(np.float32))
    np.testing.assert_array_equal(bandelets.decode(data, restore=False), plain)
    assert psnr(crease_map, outputs[()], "normal-map") > psnr(crease_map, plain, "normal-map")
    assert bdl.read_bytes() == data  # the input is never touched


def test_rgba_png_drops_alpha_with_a_warning(tmp_path, capsys):
    rgb = np.rint(np.stack([_gray((32, 32))] * 3, -1) * 255).astype(np.uint8)
    alpha = np.full((32, 32, 1), 200, np.uint8)
    png = _write_png(tmp_path / "rgba.png", np.concatenate([rgb, alpha], -1))
    bdl = tmp_path / "rgba.bdl"
    status, _, err = _run(capsys, "encode", png, bdl, "--threshold", "0.01")
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
        capsys, "encode", path, tmp_path / "o.bdl", "--wavelet", "db8", "--threshold", "0.05"
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
    code = "import sys, bandelets.cli; print(sorted({'numba', 'numpy'} & set(sys.modules)))"
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert done.stdout.strip() == "[]"
