"""Lossless files (bandelets.coding.lossless, format version 12): exact round trips, the default's choice
under a rate target, and the errors."""

from __future__ import annotations

from dataclasses import replace

import imagecodecs
import numpy as np
import pytest

import bandelets
from bandelets.apps.cli import main
from bandelets.coding import lossless
from bandelets.format.fields import FormatError
from bandelets.format.header import pack, unpack
from bandelets.format.samples import from_samples, to_samples
from bandelets.samples import crease_normal_map


def _samples(depth: int, shape: tuple, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.integers(0, 2**depth, shape).astype(np.uint8 if depth == 8 else np.uint16)


def _smooth_map(size: int, depth: int) -> np.ndarray:
    """The crease normal map as samples of ``depth`` bits."""
    return to_samples(crease_normal_map(size), "normal-map", depth)


@pytest.mark.parametrize("depth", [8, 16])
@pytest.mark.parametrize(
    "make",
    [
        lambda d: _samples(d, (23, 37, 3)),  # noise: every residual large
        lambda d: np.full((16, 20, 3), 2 ** (d - 1) + 3, np.uint8 if d == 8 else np.uint16),  # constant
        lambda d: _smooth_map(48, d),
        lambda d: np.stack([np.zeros((9, 11)), np.full((9, 11), 2**d - 1)], -1).astype(
            np.uint8 if d == 8 else np.uint16
        ),  # the extremes of the range, two channels
    ],
)
def test_normal_map_samples_round_trip_bit_exact(make, depth):
    samples = make(depth)
    data = bandelets.encode(samples, kind="normal-map", lossless=True)
    header, _ = unpack(data)
    assert (header.transform, header.depth, header.channels) == ("lossless", depth, samples.shape[2])
    decoded = bandelets.decode(data)
    # The values of the very samples given (not renormalised), which write back to them.
    assert np.array_equal(decoded, from_samples(samples, "normal-map", depth))
    assert np.array_equal(to_samples(decoded, "normal-map", depth), samples)


@pytest.mark.parametrize("channels", [1, 2, 4])
def test_image_samples_of_any_channel_count_round_trip(channels):
    samples = _samples(16, (13, 17, channels), seed=channels)[..., :channels]
    values = from_samples(samples, "image", 16)
    data = bandelets.encode(values[..., 0] if channels == 1 else values, depth=16, lossless=True)
    decoded = bandelets.decode(data)
    assert decoded.shape == ((13, 17) if channels == 1 else (13, 17, channels))
    assert np.array_equal(decoded.reshape(values.shape), values)


def test_smooth_map_is_coded_well_below_its_raw_size():
    samples = _smooth_map(64, 8)
    data = bandelets.encode(samples, kind="normal-map", lossless=True)
    assert 8 * len(data) / 64**2 < 6.0  # 24 bits per pixel raw
    assert len(data) < len(imagecodecs.png_encode(samples, level=9))


def test_default_writes_the_lossless_file_only_when_it_fits_the_rate():
    samples = _smooth_map(64, 8)
    exact = bandelets.encode(samples, kind="normal-map", lossless=True)
    rate = 8 * len(exact) / 64**2
    above = bandelets.encode(samples, kind="normal-map", bpp=rate + 0.05)
    assert above == exact
    below = bandelets.encode(samples, kind="normal-map", bpp=rate - 0.05)
    assert unpack(below)[0].transform != "lossless"
    assert 8 * len(below) <= (rate - 0.05) * 64**2
    # Not when asked not to, nor for floats off the sample grid.
    assert unpack(bandelets.encode(samples, kind="normal-map", bpp=rate + 0.05, lossless=False))[
        0
    ].transform != ("lossless")
    floats = from_samples(samples, "normal-map", 8) + 1e-6
    assert unpack(bandelets.encode(floats, kind="normal-map", bpp=rate + 1.0))[0].transform != "lossless"


def test_budget_stops_the_encoder():
    samples = _samples(8, (32, 32, 3))
    full = lossless.encode_samples(samples, 8)
    assert lossless.encode_samples(samples, 8, budget=len(full) // 2) is None
    assert lossless.encode_samples(samples, 8, budget=len(full)) == full


def test_errors_are_clear():
    floats = crease_normal_map(16)
    with pytest.raises(ValueError, match="lossless coding needs integer samples"):
        bandelets.encode(floats, kind="normal-map", lossless=True)
    with pytest.raises(ValueError, match="no target"):
        bandelets.encode(_smooth_map(16, 8), kind="normal-map", lossless=True, bpp=2.0)
    with pytest.raises(ValueError, match="geometry image"):
        bandelets.encode(floats, kind="geometry-image", lossless=True)
    with pytest.raises(ValueError, match="needs 3 channels"):
        bandelets.encode(np.zeros((8, 8, 4), np.uint8), kind="normal-map", lossless=True)


def test_corrupt_lossless_streams_are_refused():
    data = bandelets.encode(_smooth_map(32, 8), kind="normal-map", lossless=True)
    header, streams = unpack(data)
    for stream in (streams[2][: len(streams[2]) // 3], bytes(len(streams[2])), b"\xff" * len(streams[2])):
        try:
            decoded = bandelets.decode(pack(replace(header, segments=()), (b"", b"", stream)))
        except FormatError as err:
            assert "corrupt" in str(err)
        else:  # some garbage decodes to samples: they are in range
            assert decoded.shape == (32, 32, 3) and np.all(np.abs(decoded) <= 1.0)


def test_cli_lossless_png_decodes_to_the_same_samples(tmp_path, capsys):
    for depth in (8, 16):
        source = tmp_path / f"map{depth}.png"
        samples = _smooth_map(40, depth)
        source.write_bytes(imagecodecs.png_encode(samples))
        coded, out = tmp_path / f"map{depth}.bdl", tmp_path / f"out{depth}.png"
        assert main(["encode", "--kind", "normal-map", "--lossless", str(source), str(coded)]) == 0
        assert "lossless" in capsys.readouterr().err
        assert main(["decode", str(coded), str(out)]) == 0
        assert np.array_equal(imagecodecs.png_decode(out.read_bytes()), samples)
    # A rate the lossless file fits: written lossless, and the summary says so.
    again = tmp_path / "again.bdl"
    assert main(["encode", "--kind", "normal-map", "--bpp", "24", str(source), str(again)]) == 0
    assert "smaller than the 24 bpp asked" in capsys.readouterr().err
    assert again.read_bytes() == coded.read_bytes()
    # Nothing to draw: a one-line error.
    assert main(["show", str(coded), str(tmp_path / "show.png")]) == 2
    assert "lossless file has no quadtrees" in capsys.readouterr().err


def test_cli_lossless_of_a_float_source_is_a_one_line_error(tmp_path, capsys):
    source = tmp_path / "map.npy"
    np.save(source, crease_normal_map(16))
    assert main(["encode", "--kind", "normal-map", "--lossless", str(source), str(tmp_path / "m.bdl")]) == 2
    err = capsys.readouterr().err
    assert "needs integer samples" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "m.bdl").exists()


def test_a_blue_that_is_the_z_of_red_and_green_costs_little():
    samples = _smooth_map(64, 16)
    three = lossless.encode_samples(samples, 16, normals=True)
    two = lossless.encode_samples(np.ascontiguousarray(samples[..., :2]), 16)
    plain = lossless.encode_samples(samples, 16)  # without the unit-vector prediction of z
    assert len(three) < 1.1 * len(two) < len(plain)
