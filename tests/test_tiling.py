"""Tiled files (format version 9 on, :mod:`bandelets.codec.tiles`): small tiles keep these tests fast."""

from __future__ import annotations

import json

import numpy as np
import pytest

import bandelets
from bandelets.apps import cli
from bandelets.codec.encoder import encode_with_stats
from bandelets.codec.options import EncodeOptions
from bandelets.format import container
from bandelets.format.fields import FormatError
from bandelets.format.header import unpack
from bandelets.format.limits import check_encodable, encoder_memory, tile_side
from bandelets.metrics import angular_error, psnr
from bandelets.samples import crease_normal_map


@pytest.fixture(scope="module")
def normals() -> np.ndarray:
    return crease_normal_map(96)[:, :80]


@pytest.fixture(scope="module")
def tiled_file(normals) -> bytes:
    return bandelets.encode(normals, bpp=1.0, kind="normal-map", tile=32)


def test_cuts_leave_no_thin_tile():
    assert container.cuts(80, 32) == [slice(0, 32), slice(32, 64), slice(64, 80)]
    assert container.cuts(70, 32) == [slice(0, 32), slice(32, 70)]  # 6 pixels left: joined
    assert container.cuts(32, 32) == [slice(0, 32)]
    assert not container.Grid(39, 39, 32).tiled


def test_a_tiled_file_meets_its_rate_with_one_threshold_everywhere(normals, tiled_file):
    assert container.is_tiled(tiled_file)
    target = normals.shape[0] * normals.shape[1] / 8
    assert 0.97 * target <= len(tiled_file) <= target
    grid, tiles = container.read(tiled_file)
    assert len(grid.boxes) == 9
    assert len({tile()[0].threshold for tile in tiles}) == 1


def test_a_tiled_file_decodes_close_to_the_untiled_one(normals, tiled_file):
    assert bandelets.decode(tiled_file).shape == normals.shape
    # At one threshold: the same error, a few more bytes (the tiles' headers and coarse levels).
    tiled, untiled = (bandelets.encode(normals, threshold=0.01, kind="normal-map", tile=t) for t in (32, 512))
    assert len(untiled) < len(tiled) < 1.5 * len(untiled)
    errors = [psnr(normals, bandelets.decode(data), "normal-map") for data in (tiled, untiled)]
    assert errors[0] > errors[1] - 1.0


def test_a_region_decodes_only_the_tiles_it_touches(tiled_file):
    whole = bandelets.decode(tiled_file)
    region = bandelets.decode(tiled_file, region=(10, 20, 30, 40))
    assert np.array_equal(region, whole[10:40, 20:60])
    # Spoil the last tile: a region away from it still decodes, the whole file does not.
    spoiled = bytearray(tiled_file)
    spoiled[-10] ^= 0xFF
    assert np.array_equal(bandelets.decode(bytes(spoiled), region=(0, 0, 32, 32)), whole[:32, :32])
    with pytest.raises(FormatError, match="CRC32"):
        bandelets.decode(bytes(spoiled))
    with pytest.raises(ValueError, match="region"):
        bandelets.decode(tiled_file, region=(90, 0, 10, 10))


def test_a_quality_target_holds_for_the_whole_decoded_image(normals):
    options = EncodeOptions(kind="normal-map", tile=32, restore=False)
    encoded = encode_with_stats(normals, options, psnr=42.0, measured=True)
    decoded = bandelets.decode(encoded.data)
    assert encoded.psnr == pytest.approx(psnr(normals, decoded, "normal-map"), abs=1e-6)
    assert encoded.psnr >= 42.0
    assert encoded.angles.p99 == pytest.approx(angular_error(normals, decoded).p99, rel=1e-4)
    encoded = encode_with_stats(normals, options, max_angle=3.0)
    assert angular_error(normals, bandelets.decode(encoded.data)).p99 <= 3.0


def test_an_image_of_one_tile_is_a_plain_file():
    image = np.linspace(0.0, 1.0, 38 * 36).reshape(38, 36)
    data = bandelets.encode(image, threshold=0.01, tile=32)  # 6 rows left: one tile
    assert not container.is_tiled(data)
    assert data == bandelets.encode(image, threshold=0.01)
    region = bandelets.decode(data, region=(1, 2, 3, 4))
    assert np.array_equal(region, bandelets.decode(data)[1:4, 2:6])


def test_a_gray_image_tiles_and_keeps_its_shape():
    y, x = np.mgrid[0:70, 0:100] / 50
    image = np.tanh(8 * (x - 0.6 * y - 0.3))
    decoded = bandelets.decode(bandelets.encode(image, threshold=0.01, tile=32))
    assert decoded.shape == image.shape
    assert np.abs(decoded - image).max() < 0.05


def test_every_truncation_and_a_bad_table_are_one_line_format_errors(tiled_file):
    for n in range(0, len(tiled_file), 97):
        with pytest.raises(FormatError) as caught:
            bandelets.decode(tiled_file[:n])
        assert "\n" not in str(caught.value)
    table = bytearray(tiled_file)
    table[20] ^= 1  # the first tile's length: the table's CRC fails
    with pytest.raises(FormatError, match="tile table"):
        bandelets.decode(bytes(table))
    with pytest.raises(FormatError, match="tiled"):
        unpack(tiled_file)


def test_large_maps_fit_the_default_memory_limit_in_tiles():
    check_encodable(4096, 4096, 3)
    check_encodable(8192, 8192, 3)
    with pytest.raises(ValueError, match="MiB"):
        check_encodable(4096, 4096, 3, tile=0)


def test_cli_encodes_decodes_and_describes_a_tiled_file(tmp_path, normals, tiled_file, capsys):
    source = tmp_path / "n.npy"
    np.save(source, normals)
    assert (
        cli.main(["encode", str(source), str(tmp_path / "n.bdl"), "--kind", "normal-map", "--tile", "32"])
        == 0
    )
    assert "PSNR" in capsys.readouterr().err
    assert cli.main(["info", str(tmp_path / "n.bdl")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["tiles"], info["tile"], info["width"], info["height"]) == (9, 32, 80, 96)
    assert info["bytes"] == (tmp_path / "n.bdl").stat().st_size
    assert cli.main(["decode", str(tmp_path / "n.bdl"), str(tmp_path / "d.npy")]) == 0
    assert np.load(tmp_path / "d.npy").shape == normals.shape


def test_by_default_only_what_does_not_fit_in_one_piece_is_tiled():
    assert tile_side(2048, 2048, 3) == 0  # one piece fits the default limit: no seams
    assert tile_side(4096, 4096, 3) == container.TILE
    assert tile_side(2048, 2048, 3, tile=300) == 300
    y, x = np.mgrid[0:2000, 0:40] / 50
    image = np.tanh(8 * (x - 0.6 * y - 0.3))
    assert not container.is_tiled(bandelets.encode(image, threshold=0.01))
    tight = encoder_memory(2000, 40, 1) - 1  # one piece no longer fits: four tiles of TILE rows
    data = bandelets.encode(image, threshold=0.01, max_memory=tight)
    assert container.is_tiled(data) and len(container.read(data)[0].boxes) == 4


def test_the_last_pass_restores_the_tiles_already_coded_to_the_same_file(normals):
    # A tiled encode's last pass reads back each tile's file and restores it rather than coding
    # the tile again: the same file and PSNR as coding it with the restoration.
    options = EncodeOptions(kind="normal-map")
    tile = normals[:48, :40]
    plain = encode_with_stats(tile, EncodeOptions(kind="normal-map", restore=False), threshold=0.003)
    fresh = encode_with_stats(tile, options, threshold=0.003, measured=True)
    again = encode_with_stats(tile, options, threshold=0.003, measured=True, unrestored=plain)
    assert unpack(fresh.data)[0].restoration > 0
    assert again.data == fresh.data and again.psnr == fresh.psnr
    np.testing.assert_array_equal(again.decoded, fresh.decoded)


def test_the_restoration_of_all_tiles_together_stays_within_max_work(normals):
    # Each tile restores within its share of max_work (by its pixels), and the decoder refuses
    # a file whose tiles together ask for more: not max_work once per tile.
    from bandelets.format.limits import restoration_work

    budget = 12 * (32 * 32 * 2 + 2**16) * 9  # about 12 iterations of every one of the 9 tiles
    data = bandelets.encode(normals, threshold=0.003, kind="normal-map", tile=32, max_work=budget)
    grid, tiles = container.read(data)
    # And every tile counts a fixed work (issue 40).
    work = sum(restoration_work(tile()[0]) for tile in tiles) + len(tiles) * container.TILE_WORK
    assert len(tiles) * container.TILE_WORK < work <= budget
    assert bandelets.decode(data, max_work=work).shape == normals.shape
    with pytest.raises(FormatError, match="max_work"):
        bandelets.decode(data, max_work=work - 1)
