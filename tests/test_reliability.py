"""Regressions of issue 18: degenerate inputs, bounded work, and the errors of the API and CLI."""

from __future__ import annotations

import struct
import subprocess
import sys
import time
import tracemalloc
import warnings
import zlib
from dataclasses import replace
from pathlib import Path

import imagecodecs
import numpy as np
import pytest
import trimesh

import bandelets
from bandelets.apps import cli
from bandelets.format.fields import MAX_THRESHOLD, MAX_WORK, MIN_THRESHOLD, FormatError
from bandelets.format.header import Header, pack, unpack
from bandelets.format.limits import restoration_work
from bandelets.io import files
from bandelets.io.files import read_array
from bandelets.restore.restoration import penalty_gradient
from bandelets.runtime import compilation
from bandelets.samples import crease_normal_map
from bandelets.surfaces.checks import MEMORY_PER_FACE
from bandelets.surfaces.codec import (
    MESH_BYTES_PER_PIXEL,
    decode_mesh,
    encode_mesh,
    load_mesh,
    make_geometry_image,
)

DATA = Path(__file__).resolve().parent / "data"


def _run(capsys, *argv) -> tuple[int, str]:
    status = cli.main([str(a) for a in argv])
    return status, capsys.readouterr().err


def _one_line_error(capsys, folder: Path, *argv) -> str:
    """Run the CLI; it must fail with one error line and leave ``folder`` as it was."""
    before = sorted(p.name for p in folder.iterdir())
    status, err = _run(capsys, *argv)
    err = "".join(line for line in err.splitlines(keepends=True) if line.strip() != compilation.MESSAGE)
    assert status == 2 and len(err.splitlines()) == 1 and err.startswith("bandelets: error:"), err
    assert sorted(p.name for p in folder.iterdir()) == before, "a file was left behind"
    return err


# ---------------------------------------------------------------------------------------------
# Black, constant and vanishing images.


@pytest.mark.parametrize("value", [0.0, 1e-200, -1e-200])
@pytest.mark.parametrize("target", [{"bpp": 1.0}, {"psnr": 40.0}, {"threshold": 0.1}])
def test_a_black_image_encodes_to_a_tiny_file_that_decodes_exactly(value, target):
    x = np.full((32, 32), value)
    data = bandelets.encode(x, **target)
    assert len(data) < 80
    assert np.abs(bandelets.decode(data) - x).max() <= abs(value)  # 1e-200 is below any threshold
    assert MIN_THRESHOLD <= unpack(data)[0].threshold <= MAX_THRESHOLD


def test_a_constant_image_encodes_to_a_tiny_file():
    x = np.full((32, 40, 3), 0.3)
    data = bandelets.encode(x, bpp=1.0)
    assert len(data) < 100
    assert np.abs(bandelets.decode(data) - x).max() < 1e-6


@pytest.mark.parametrize("z", [1.0, -1.0, 0.0])  # 0: zero vectors, renormalised to +z
@pytest.mark.parametrize("target", [{"bpp": 1.0}, {"psnr": 40.0}])
def test_a_flat_normal_map_encodes(z, target):
    x = np.zeros((32, 32, 3))
    x[..., 2] = z
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the command line would print them
        data = bandelets.encode(x, kind="normal-map", **target)
    expected = np.array([0.0, 0.0, -1.0 if z < 0 else 1.0])
    assert len(data) < 100
    assert np.abs(bandelets.decode(data) - expected).max() < 1e-9


def test_cli_encodes_a_black_png(tmp_path, capsys):
    png = tmp_path / "black.png"
    png.write_bytes(imagecodecs.png_encode(np.zeros((32, 32), np.uint8)))
    for extra in ([], ["--psnr", "40"]):
        assert _run(capsys, "encode", png, tmp_path / "b.bdl", "-f", *extra)[0] == 0
        assert _run(capsys, "decode", tmp_path / "b.bdl", tmp_path / "b.png", "-f")[0] == 0
        assert not imagecodecs.png_decode((tmp_path / "b.png").read_bytes()).any()


# ---------------------------------------------------------------------------------------------
# Thresholds a file may hold.


def _normal_map_file(z: float = 1.0, restoration: int = 5) -> tuple[Header, tuple]:
    x = crease_normal_map(32)
    x[..., 2] *= z
    header, streams = unpack(bandelets.encode(x, threshold=0.05, kind="normal-map", restore=False))
    return replace(header, restoration=restoration), streams


@pytest.mark.parametrize("threshold", [1e-45, MIN_THRESHOLD / 2, 1e-37, 1e37, MAX_THRESHOLD * 2, 3e38])
def test_decoder_refuses_a_threshold_out_of_range(threshold):
    header, streams = _normal_map_file()
    with pytest.raises(ValueError, match="threshold"):  # the encoder cannot write it
        pack(replace(header, threshold=threshold), streams)
    body = bytearray(pack(header, streams)[:-4])
    struct.pack_into("<f", body, 10, threshold)  # the float32 threshold of the header
    with pytest.raises(FormatError, match="bad threshold"):
        bandelets.decode(bytes(body) + struct.pack("<I", zlib.crc32(body)))


@pytest.mark.parametrize("z", [1.0, -1.0])  # two coded channels, and three in local frames
@pytest.mark.parametrize("threshold", [MIN_THRESHOLD, MAX_THRESHOLD])
def test_extreme_thresholds_decode_to_unit_vectors(z, threshold):
    header, streams = _normal_map_file(z)
    with np.errstate(all="raise"):
        out = bandelets.decode(pack(replace(header, threshold=threshold), streams))
    assert np.allclose(np.linalg.norm(out, axis=-1), 1.0)


def test_the_restoration_penalty_is_finite_when_its_smoothing_underflows():
    x = np.zeros((2, 8, 8))
    x[:, 3:, :] = 1e-300
    g = penalty_gradient(x, 1e-200, 1e-199, 0.25, 1e-199)
    assert np.all(np.isfinite(g))


def test_encoder_refuses_thresholds_out_of_range():
    for threshold in (1e-101, 1e101, float("nan"), 0.0):
        with pytest.raises(ValueError, match="threshold must be from"):
            bandelets.encode(np.zeros((8, 8)), threshold=threshold)


# ---------------------------------------------------------------------------------------------
# Bounded work.


def test_a_tiny_file_asking_for_hours_of_restoration_is_refused_at_once():
    """Issue 18: 1.6 KB for a near-empty 3000 x 3000 image restored 100 times kept a decoder busy 113 s."""
    header = Header(
        height=3000,
        width=3000,
        channels=1,
        kind="image",
        transform="bandelet",
        wavelet="cdf97",
        levels=6,
        threshold=0.1,
        restoration=100,
    )
    data = pack(header, (b"\x00" * 20, b"\x00" * 20, b"\x00" * 1500))
    assert restoration_work(header) > MAX_WORK
    start = time.perf_counter()
    with pytest.raises(FormatError, match="max_work"):
        bandelets.decode(data)
    assert time.perf_counter() - start < 0.5
    with pytest.raises(ValueError, match="max_work"):
        bandelets.decode(data, max_work=restoration_work(header) - 1)


def test_max_work_is_exact_and_the_encoder_keeps_within_it():
    header, streams = _normal_map_file(restoration=30)
    data = pack(header, streams)
    need = restoration_work(header)
    with pytest.raises(FormatError, match="max_work"):
        bandelets.decode(data, max_work=need - 1)
    assert bandelets.decode(data, max_work=need).shape == (32, 32, 3)
    assert bandelets.decode(data, max_work=0, restore=False).shape == (32, 32, 3)
    x = crease_normal_map(32)
    chosen = unpack(bandelets.encode(x, threshold=0.05, kind="normal-map"))[0].restoration
    assert chosen > 2  # the test means something: the encoder restores this map
    per_iteration = restoration_work(replace(header, restoration=1))
    capped = bandelets.encode(x, threshold=0.05, kind="normal-map", max_work=2 * per_iteration)
    assert unpack(capped)[0].restoration <= 2
    bandelets.decode(capped, max_work=2 * per_iteration)


@pytest.mark.parametrize("shape", [(8, 20000), (16385, 2)])
def test_encoder_refuses_what_the_default_decoder_refuses(shape):
    with pytest.raises(ValueError, match="exceeds what decoders accept by default"):
        bandelets.encode(np.zeros(shape), bpp=1.0)


def _png_header_only(width: int, height: int, depth: int = 8, colour: int = 0) -> bytes:
    """A PNG's signature and IHDR chunk (a decoder would then need IDAT chunks)."""
    body = b"IHDR" + struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + body + struct.pack(">I", zlib.crc32(body))


def test_a_huge_png_is_refused_from_its_header(tmp_path):
    """Issue 18: a 389 KB PNG of 20000 x 20000 zeros reached 3.7 GB before the refusal."""
    path = tmp_path / "huge.png"
    path.write_bytes(_png_header_only(20000, 20000, 16, 2) + b"\x00" * 1000)
    tracemalloc.start()
    with pytest.raises(ValueError, match=r"huge.png: encoding a 20000 x 20000 x 3 image needs about"):
        read_array(path, "image")
    assert tracemalloc.get_traced_memory()[1] < 2**20
    tracemalloc.stop()
    path.write_bytes(_png_header_only(20, 20, 3, 2))
    with pytest.raises(ValueError, match="bit depth 3"):
        read_array(path, "image")


def test_a_huge_npy_is_refused_from_its_header(tmp_path):
    path = tmp_path / "huge.npy"
    # 256 MB announced (sparse): above the memory of even a tiled encode (bandelets.codec.tiles).
    np.lib.format.open_memmap(path, mode="w+", dtype=np.uint8, shape=(16000, 16000)).flush()
    tracemalloc.start()
    with pytest.raises(ValueError, match="huge.npy: encoding a 16000 x 16000 x 1 image needs about"):
        read_array(path, "image")
    assert tracemalloc.get_traced_memory()[1] < 2**20
    tracemalloc.stop()


# ---------------------------------------------------------------------------------------------
# Meshes.

# A closed octahedron whose top vertex lies exactly on the edge between +x and +y: one triangle
# of zero area (issue 18: ZeroDivisionError in the parameterization).
_FLAT_OCTAHEDRON = """v 1 0 0
v -1 0 0
v 0 1 0
v 0 -1 0
v 0.5 0.5 0
v 0 0 -1
f 1 3 5
f 3 2 5
f 2 4 5
f 4 1 5
f 3 1 6
f 2 3 6
f 4 2 6
f 1 4 6
"""


@pytest.mark.parametrize("command", ["mesh-encode", "geometry-image"])
def test_a_zero_area_triangle_is_refused(tmp_path, capsys, command):
    mesh = tmp_path / "flat.obj"
    mesh.write_text(_FLAT_OCTAHEDRON)
    out = tmp_path / ("out.bdl" if command == "mesh-encode" else "out.npy")
    err = _one_line_error(capsys, tmp_path, command, mesh, out, "--size", "16")
    assert "1 face of zero area" in err


def test_a_mesh_too_large_for_max_memory_is_refused_before_the_work():
    mesh = trimesh.creation.icosphere(3)
    limit = MEMORY_PER_FACE * len(mesh.faces) - 1
    for run in (
        lambda: make_geometry_image(mesh, 16, max_memory=limit),
        lambda: encode_mesh(mesh, size=16, max_memory=limit),
    ):
        start = time.perf_counter()
        with pytest.raises(
            ValueError, match=r"parameterizing a mesh of 1280 faces needs about .* \(max_memory\)"
        ):
            run()
        assert time.perf_counter() - start < 0.5


def test_a_mesh_too_large_to_rebuild_is_refused_by_the_encoder_and_the_decoder():
    mesh = trimesh.creation.icosphere(1)
    data = encode_mesh(mesh, size=16, bpp=8.0)
    limit = MESH_BYTES_PER_PIXEL * 16 * 16
    assert len(decode_mesh(data, vertices="full", max_memory=limit).vertices) > len(mesh.vertices)
    with pytest.raises(ValueError, match=r"a mesh of 16 x 16 vertices needs about .* \(max_memory\)"):
        decode_mesh(data, max_memory=limit - 1)
    with pytest.raises(ValueError, match=r"a mesh of 2048 x 2048 vertices needs about"):
        encode_mesh(mesh, size=2048)  # the default limit, before the work


def test_undecodable_mesh_text_names_no_missing_module(tmp_path, monkeypatch):
    """trimesh imports charset_normalizer to guess the encoding of non-UTF-8 text."""
    monkeypatch.setitem(sys.modules, "charset_normalizer", None)  # as if not installed
    path = tmp_path / "random.stl"
    path.write_bytes(np.random.default_rng(3).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    with pytest.raises(ValueError) as caught:
        load_mesh(path)
    assert "module" not in str(caught.value) and str(caught.value).startswith(str(path))


def test_geometry_image_outputs_both_or_neither(tmp_path, capsys, monkeypatch):
    mesh = tmp_path / "sphere.obj"
    trimesh.creation.icosphere(2).export(mesh)
    positions = tmp_path / "g.npy"
    err = _one_line_error(capsys, tmp_path, "geometry-image", mesh, positions, "--normals", positions)
    assert "--normals would overwrite the positions" in err
    # The normals fail to be written after the positions were: the positions go too.
    write = files.write_array

    def failing(path, *args):
        if Path(path).suffix == ".png":
            raise OSError(28, "No space left on device", str(path))
        write(path, *args)

    monkeypatch.setattr(files, "write_array", failing)
    err = _one_line_error(
        capsys, tmp_path, "geometry-image", mesh, positions, "--size", "8", "--normals", tmp_path / "n.png"
    )
    assert "No space left" in err


# ---------------------------------------------------------------------------------------------
# Errors of the API and the command line.


@pytest.mark.parametrize("data", ["abc", 3.5, None, [1, 2]])
def test_decode_of_something_else_than_bytes_is_a_type_error(data):
    with pytest.raises(TypeError, match="decode takes the bytes of a .bdl file"):
        bandelets.decode(data)


def test_decode_takes_any_buffer():
    data = (DATA / "gray16.bdl").read_bytes()
    expected = bandelets.decode(data)
    for buffer in (bytearray(data), memoryview(data), np.frombuffer(data, np.uint8)):
        assert np.array_equal(bandelets.decode(buffer), expected)


@pytest.mark.parametrize("target", [{"bpp": "1"}, {"threshold": "0.1"}, {"psnr": b"40"}])
def test_a_target_that_is_not_a_number_is_a_type_error(target):
    with pytest.raises(TypeError, match="must be a number, got"):
        bandelets.encode(np.zeros((8, 8)), **target)


@pytest.mark.parametrize("option", ["--psnr", "--bpp", "--threshold"])
@pytest.mark.parametrize("value", ["-1", "0", "inf", "nan"])
def test_cli_refuses_a_target_that_is_not_positive(tmp_path, capsys, option, value):
    png = tmp_path / "in.png"
    png.write_bytes(imagecodecs.png_encode(np.zeros((8, 8), np.uint8)))
    err = _one_line_error(capsys, tmp_path, "encode", png, tmp_path / "o.bdl", option, value)
    assert "must be a positive number" in err


def test_psnr_target_must_be_positive():
    with pytest.raises(ValueError, match="psnr must be a positive number"):
        bandelets.encode(np.zeros((8, 8)), psnr=-1.0)


def test_an_unwritable_destination_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    folder = Path("/sys")
    try:
        with open(folder / "bandelets-probe", "wb"):
            pass
        pytest.skip("/sys is writable here")
    except OSError:
        pass

    def never(*args, **kwargs):
        raise AssertionError("the input was read before the destination was checked")

    monkeypatch.setattr(files, "read_array", never)
    png = tmp_path / "in.png"
    png.write_bytes(imagecodecs.png_encode(np.zeros((8, 8), np.uint8)))
    err = _one_line_error(capsys, tmp_path, "encode", png, folder / "out.bdl")
    assert "cannot write in folder /sys" in err and ".tmp" not in err
    with pytest.raises(OSError) as caught:
        files.write_atomic(folder / "out.bdl", b"x")
    assert caught.value.filename == str(folder / "out.bdl")


def test_the_fuzz_harness_runs_as_the_readme_says(tmp_path):
    pytest.importorskip("atheris")
    done = subprocess.run(
        [
            sys.executable,
            str(Path(__file__).parent / "fuzz" / "fuzz_decode.py"),
            "-runs=30",
            str(tmp_path / "c"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "[fuzz_decode] 30 inputs" in done.stderr


def test_a_huge_tiff_is_refused_from_its_header(tmp_path):
    import tifffile

    path = tmp_path / "huge.tif"
    tifffile.memmap(path, shape=(20000, 20000), dtype=np.uint16).flush()  # sparse: 800 MB announced
    tracemalloc.start()
    with pytest.raises(ValueError, match="huge.tif: encoding a 20000 x 20000 x 1 image needs about"):
        read_array(path, "image")
    assert tracemalloc.get_traced_memory()[1] < 2**22
    tracemalloc.stop()


@pytest.mark.parametrize("suffix", [".png", ".npy", ".exr", ".tif"])
def test_image_shape_reads_the_header_of_every_format(tmp_path, suffix):
    from bandelets.io.files import image_shape, write_array

    path = tmp_path / f"map{suffix}"
    write_array(path, np.zeros((20, 30, 3)), "normal-map", 16)
    assert image_shape(path) == (20, 30, 3)
    path.write_bytes(b"not an image at all, but long enough to hold a header")
    with pytest.raises(ValueError, match="map"):
        image_shape(path)
