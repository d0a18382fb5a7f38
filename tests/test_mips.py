"""Mip levels from a prefix of a .bdl file (format version 19, issue 39): every level of a generated
and a real normal map decodes from the file cut after its bytes exactly as from the whole file, its
angle from a reference mip of the original, --green round trips, and the CLI's KTX2 / DDS files
read back by texture2ddecoder."""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np
import pytest
import texture2ddecoder

from bandelets import decode, encode
from bandelets.apps.cli import main
from bandelets.codec.levels import level_bytes
from bandelets.format.fields import FormatError
from bandelets.format.header import unpack
from bandelets.io.gpu import mip_chain
from bandelets.metrics import angles
from bandelets.samples import bump_normal_map
from bandelets.transform.normals import unit_vectors

REAL = (
    Path(__file__).resolve().parents[1]
    / ".."
    / "shared"
    / "data"
    / "normal-maps"
    / "flighthelmet_leather_512.png"
)


def mean_angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(angles(a, b).mean())


def real_map() -> np.ndarray:
    if not REAL.is_file():
        pytest.skip(f"{REAL} is absent (the shared data beside the checkout)")
    import imageio.v3 as iio

    rgb = iio.imread(REAL)[:256, :256, :3].astype(np.float64) / 255 * 2 - 1
    return unit_vectors(rgb)


@pytest.fixture(scope="module", params=["generated", "real"])
def coded(request) -> tuple[np.ndarray, bytes]:
    source = bump_normal_map(128) if request.param == "generated" else real_map()
    return source, encode(source, bpp=1.0, kind="normal-map")


def test_every_level_decodes_from_its_prefix_exactly(coded) -> None:
    _, data = coded
    header = unpack(data)[0]
    needs = level_bytes(data)
    assert needs[0] == len(data) and needs == sorted(needs, reverse=True) and len(needs) == header.levels + 1
    for k in range(1, header.levels + 1):
        whole = decode(data, level=k)
        assert whole.shape[:2] == (-(-header.height >> k), -(-header.width >> k))
        assert np.array_equal(decode(data[: needs[k]], level=k), whole)
        assert np.allclose(np.linalg.norm(whole, axis=-1), 1.0)
        with pytest.raises(FormatError, match=f"does not hold level {k}"):
            decode(data[: needs[k] - 1], level=k)
    beyond = decode(data[: needs[-1]], level=header.levels + 1)
    assert beyond.shape[:2] == (-(-header.height >> (header.levels + 1)),) * 2


def test_level_images_against_reference_mips(coded) -> None:
    """The level-k image's mean angle from the reference mip (box average of the original's unit
    vectors, renormalised) at levels 1 and 2 stays within 1.5 degrees of that of the mip of the full
    decode (measured: +0.2 to +1.4; the issue asked 0.1, not met: the wavelet's low-pass is not a box,
    see the xfail below; the coarser levels of the generated bumps are 3.5 degrees off)."""
    source, data = coded
    reference, full = mip_chain(source), mip_chain(decode(data))
    for k in (1, 2):
        level = decode(data, level=k)
        assert mean_angle(level, reference[k]) <= mean_angle(full[k], reference[k]) + 1.5


@pytest.mark.xfail(
    strict=True, reason="issue 39's bound of 0.1 degree: the coarse approximation is not a box mip"
)
def test_level_one_within_a_tenth_of_a_degree(coded) -> None:
    source, data = coded
    reference, full = mip_chain(source), mip_chain(decode(data))
    assert mean_angle(decode(data, level=1), reference[1]) <= mean_angle(full[1], reference[1]) + 0.1


def test_lossless_and_bad_levels_are_refused() -> None:
    data = encode(
        np.round((bump_normal_map(32) * 0.5 + 0.5) * 255).astype(np.uint8), kind="normal-map", lossless=True
    )
    with pytest.raises(FormatError, match="level 0 only"):
        decode(data, level=1)
    with pytest.raises(ValueError, match="level"):
        decode(encode(bump_normal_map(32), bpp=1.0, kind="normal-map"), level=-1)


def write_png(path: Path, normals: np.ndarray) -> None:
    import imageio.v3 as iio

    iio.imwrite(path, np.round((normals * 0.5 + 0.5) * 255).astype(np.uint8))


def test_green_round_trip_flips_y_and_nothing_else(tmp_path: Path) -> None:
    write_png(tmp_path / "in.png", bump_normal_map(64))
    assert main(["encode", str(tmp_path / "in.png"), str(tmp_path / "m.bdl"), "--kind", "normal-map",
                 "--green", "down", "-q"]) == 0  # fmt: skip
    data = (tmp_path / "m.bdl").read_bytes()
    assert unpack(data)[0].green == "down"
    for green in ("down", "up"):
        out = tmp_path / f"{green}.npy"
        assert main(["decode", str(tmp_path / "m.bdl"), str(out), "--green", green, "-q"]) == 0
    same, flipped = np.load(tmp_path / "down.npy"), np.load(tmp_path / "up.npy")
    assert np.array_equal(same, decode(data).astype(np.float32))
    assert np.array_equal(flipped[..., 1], -same[..., 1])
    assert np.array_equal(np.delete(flipped, 1, axis=-1), np.delete(same, 1, axis=-1))


def test_cli_gpu_files_read_back_independently(tmp_path: Path, capsys) -> None:
    """texture2ddecoder reads level 0's BC5 blocks of the KTX2 and DDS files the CLI writes, and their
    angle from the decoded map is the one the summary line reports."""
    write_png(tmp_path / "in.png", bump_normal_map(64))
    assert (
        main(["encode", str(tmp_path / "in.png"), str(tmp_path / "m.bdl"), "--kind", "normal-map", "-q"]) == 0
    )
    decoded = decode((tmp_path / "m.bdl").read_bytes())
    for name in ("m.ktx2", "m.dds"):
        capsys.readouterr()
        assert main(["decode", str(tmp_path / "m.bdl"), str(tmp_path / name), "--mips"]) == 0
        reported = float(re.search(r"BC5 adds ([0-9.]+) deg", capsys.readouterr().err).group(1))
        data = (tmp_path / name).read_bytes()
        if name.endswith(".ktx2"):
            assert data[:12] == b"\xabKTX 20\xbb\r\n\x1a\n"
            levels = struct.unpack_from("<I", data, 40)[0]
            offset, length, _ = struct.unpack_from("<3Q", data, 80)
        else:
            assert data[:4] == b"DDS "
            levels = struct.unpack_from("<I", data, 28)[0]
            offset, length = 148, 64 * 64  # the DX10 header; BC5: 16 bytes a 4 x 4 block
        assert levels == 7  # 64 x 64 to 1 x 1
        rgba = texture2ddecoder.decode_bc5(data[offset : offset + length], 64, 64)
        bgra = np.frombuffer(rgba, np.uint8).reshape(64, 64, 4).astype(np.float64)
        xy = np.dstack([bgra[..., 2], bgra[..., 1]]) / 255 * 2 - 1
        assert mean_angle(xy, decoded) == pytest.approx(reported, abs=0.002)


def test_cli_mips_of_an_image_output(tmp_path: Path) -> None:
    write_png(tmp_path / "in.png", bump_normal_map(32))
    assert (
        main(["encode", str(tmp_path / "in.png"), str(tmp_path / "m.bdl"), "--kind", "normal-map", "-q"]) == 0
    )
    assert (
        main(["decode", str(tmp_path / "m.bdl"), str(tmp_path / "o.npy"), "--mips", "--level", "1", "-q"])
        == 0
    )
    shapes = [np.load(tmp_path / f"o-{k}.npy").shape[:2] for k in range(5)]
    assert shapes == [(16, 16), (8, 8), (4, 4), (2, 2), (1, 1)]
    assert not (tmp_path / "o-5.npy").exists()


def test_tiled_file_decodes_each_tile_at_the_level() -> None:
    """Each tile at level k from its first bytes, side by side: sides of ceil(tile / 2^k)."""
    source = bump_normal_map(96)
    data = encode(source, bpp=1.0, kind="normal-map", tile=32)
    needs = level_bytes(data)
    assert needs[0] == len(data) and needs[1] < len(data)
    for k in range(1, 5):
        image = decode(data, level=k)
        assert image.shape == (-(-96 >> k), -(-96 >> k), 3)
        assert np.allclose(np.linalg.norm(image, axis=-1), 1.0)
    assert mean_angle(decode(data, level=1), mip_chain(source)[1]) < 3.0


def test_every_cut_decodes_or_is_refused_in_one_line() -> None:
    """A file cut anywhere decodes at level 1 (when the cut holds it) or raises FormatError."""
    data = encode(bump_normal_map(32), bpp=2.0, kind="normal-map")
    needs = level_bytes(data)
    whole = decode(data, level=1)
    for cut in range(0, len(data), 3):
        try:
            image = decode(data[:cut], level=1)
        except FormatError:
            assert cut < needs[1]
        else:
            assert cut >= needs[1] and np.array_equal(image, whole)


def test_cli_decodes_a_cut_file_at_its_level(tmp_path: Path, capsys) -> None:
    write_png(tmp_path / "in.png", bump_normal_map(64))
    assert (
        main(["encode", str(tmp_path / "in.png"), str(tmp_path / "m.bdl"), "--kind", "normal-map", "-q"]) == 0
    )
    data = (tmp_path / "m.bdl").read_bytes()
    needs = level_bytes(data)
    (tmp_path / "cut.bdl").write_bytes(data[: needs[2]])
    assert main(["decode", str(tmp_path / "cut.bdl"), str(tmp_path / "two.npy"), "--level", "2", "-q"]) == 0
    assert np.array_equal(np.load(tmp_path / "two.npy"), decode(data, level=2).astype(np.float32))
    capsys.readouterr()
    assert main(["decode", str(tmp_path / "cut.bdl"), str(tmp_path / "one.npy"), "--level", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"needs the first {needs[1]} bytes" in err


def test_batch_to_ktx2_ships_every_file_beside_its_bdl(tmp_path: Path, monkeypatch) -> None:
    """``batch --to ktx2 --mips``: each .bdl file of the report (not the failed ones) decoded beside it
    (the batch itself replaced by its report, so that no cluster starts)."""
    import pandas as pd

    from bandelets.apps import batch

    bdl = tmp_path / "m.bdl"
    bdl.write_bytes(encode(bump_normal_map(32), bpp=1.0, kind="normal-map"))
    rows = [
        {"input": "m.png", "output": str(bdl), "status": "ok", "error": ""},
        {"input": "bad.png", "output": str(tmp_path / "bad.bdl"), "status": "failed", "error": "not a PNG"},
    ]
    monkeypatch.setattr(batch, "batch", lambda *args, **kwargs: pd.DataFrame(rows))
    argv = ["batch", "m.png", "--out", str(tmp_path), "--kind", "normal-map", "--to", "ktx2", "--mips"]
    assert main(argv) == 1  # the failed row
    data = (tmp_path / "m.ktx2").read_bytes()
    assert data[:12] == b"\xabKTX 20\xbb\r\n\x1a\n" and struct.unpack_from("<I", data, 40)[0] == 6
    assert not (tmp_path / "bad.ktx2").exists()
