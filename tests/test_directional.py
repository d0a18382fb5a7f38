"""Direction-adaptive lifting: exact inverse, plain CDF 9/7 without directions, the codec's use."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import straight_edge

import bandelets
from bandelets import directional, entropy, lifting
from bandelets.bitstream import FormatError, pack, unpack
from bandelets.metrics import psnr
from bandelets.samples import bump_normal_map, crease_normal_map
from bandelets.wavelets import wavedec

_TABLES = (directional.OFFSETS, directional.WEIGHTS, directional.SCALES)


def test_synthesis_inverts_analysis_whatever_the_directions(rng):
    channels = [rng.normal(size=(64, 48)) for _ in range(2)]
    coefficients, fields = directional.analysis(channels, 3, 2, threshold=0.1)
    assert any(np.any(f) for f in fields)  # noise picks some direction somewhere
    random = [rng.integers(0, len(directional.OFFSETS), f.shape) for f in fields]
    for chosen in (fields, random):
        coefficients, _ = directional.analysis(channels, 3, 2, chosen)
        for c, x in zip(coefficients, channels, strict=True):
            np.testing.assert_allclose(directional.synthesis(c, 3, 2, chosen), x, atol=1e-10)


def test_plain_directions_are_the_cdf97_wavelet(rng):
    x = rng.normal(size=(32, 64))
    plain = [np.zeros(shape, np.int64) for shape in directional.field_shapes(x.shape, 2)]
    np.testing.assert_allclose(
        directional.analysis([x], 4, 2, plain)[0][0], wavedec(x, "cdf97", 4), atol=1e-12
    )


@pytest.mark.parametrize("transposed", [False, True])
def test_a_plain_directional_pass_is_the_cdf97_pass_to_the_last_bit(rng, transposed):
    x = rng.normal(size=(24, 40))
    source = x.T if transposed else x  # a column pass is handed transposes
    codes = np.zeros((-(-source.shape[0] // 8), -(-source.shape[1] // 8)), np.int64)
    plain, lifted = (np.empty(source.shape[::-1]).T if transposed else np.empty(source.shape) for _ in "ab")
    lifting.cdf97_pass(source, plain, True)
    lifting.directional_pass(source, lifted, True, codes, *_TABLES, 8)
    np.testing.assert_array_equal(lifted, plain)
    back = np.empty(source.shape[::-1]).T if transposed else np.empty(source.shape)
    lifting.directional_pass(lifted, back, False, codes, *_TABLES, 8)
    np.testing.assert_allclose(back, source, atol=1e-12)


def test_direction_costs_count_the_high_pass_of_each_slope(rng):
    x = rng.normal(size=(16, 32))
    costs = lifting.direction_costs(x, *_TABLES, 8, 0.5)
    assert costs.shape == (len(directional.OFFSETS), 2, 4)
    plain = np.empty_like(x)
    lifting.cdf97_pass(x, plain, True)
    d = plain[:, 16:] * lifting.ZETA  # before the final scaling
    bits = np.log2(1.0 + 4.0 * np.abs(d)).reshape(2, 8, 4, 4).sum(axis=(1, 3))
    np.testing.assert_allclose(costs[0], bits, rtol=1e-12)
    # A pattern along slope 1 (rows per column step) costs least along it.
    diagonal = np.subtract.outer(np.arange(16), np.arange(32)) % 4 < 2  # constant along r - c
    slope_one = list(directional.OFFSETS).index(1.0)
    assert np.all(
        np.argmin(
            lifting.direction_costs(diagonal.astype(float), *_TABLES, 8, 0.5)[:, 1:, 1:-1], axis=0
        )
        == slope_one
    )


def test_directions_pay_on_creases_not_on_smooth_bumps():
    for sample, threshold, expected in ((crease_normal_map, 0.01, True), (bump_normal_map, 0.005, False)):
        channels = list(np.moveaxis(sample(256)[..., :2], -1, 0))
        lifted, fields = directional.analysis(channels, 6, 2, threshold=threshold)
        assert any(np.any(f) for f in fields)  # some block finds a direction, even on the bumps
        assert directional.pays(channels, lifted, fields, 6, 2, threshold) is expected


def test_a_normal_map_is_lifted_by_default_only_where_directions_pay():
    bumps = bump_normal_map(64)
    for requested, expected in ((True, directional.LEVELS), (None, 0), (False, 0)):
        assert (
            unpack(bandelets.encode(bumps, threshold=0.001, kind="normal-map", lifting=requested))[0].lifting
            == expected
        )


def test_an_oblique_edge_leaves_fewer_fine_coefficients():
    x = straight_edge(64, angle_deg=63.0, blur=0.5)
    lifted, fields = directional.analysis([x], 3, 2, threshold=0.01)
    plain = wavedec(x, "cdf97", 3)
    fine = np.ones(x.shape, bool)
    fine[:32, :32] = False  # the finest level's three subbands
    assert np.any(fields[0])
    assert np.sum(np.abs(lifted[0][fine])) < 0.7 * np.sum(np.abs(plain[fine]))


def test_directions_round_trip_through_the_coder(rng):
    shape = (64, 96)
    fields = [
        rng.integers(0, len(directional.OFFSETS), s) * rng.integers(0, 2, s)
        for s in directional.field_shapes(shape, 2)
    ]
    coder = entropy.Coder(directional.N_CONTEXTS)
    directional.code_fields(coder, fields, shape, 2, 0)
    decoded = directional.code_fields(
        entropy.Coder(directional.N_CONTEXTS, coder.finish()), None, shape, 2, 0
    )
    for a, b in zip(fields, decoded, strict=True):
        np.testing.assert_array_equal(a, b)


def test_normal_maps_are_lifted_on_request(crease_map):
    data = {
        lifting: bandelets.encode(
            crease_map, threshold=0.01, kind="normal-map", lifting=lifting, restore=False
        )
        for lifting in (True, False, None)
    }
    assert unpack(data[True])[0].lifting == directional.LEVELS
    assert unpack(data[False])[0].lifting == 0
    # On the small map the directions do not pay: by default the file is coded without them.
    assert data[None] == data[False]
    quality = {k: psnr(crease_map, bandelets.decode(d), "normal-map") for k, d in data.items()}
    # The same threshold gives about the same quality (the gain, a smaller file for it, shows on
    # larger maps: benchmarks/rd_normal_maps.py).
    assert abs(quality[True] - quality[False]) < 1.0
    assert quality[True] > 40
    # On a larger one they pay: lifted by default (not for an image).
    crease = crease_normal_map(256)
    assert unpack(bandelets.encode(crease, threshold=0.01, kind="normal-map", restore=False))[0].lifting == 2
    assert unpack(bandelets.encode(crease[..., 0], threshold=0.01, restore=False))[0].lifting == 0


def test_three_channel_normal_maps_are_lifted_in_local_frames():
    v, u = np.mgrid[0:32, 0:32] / 31.0
    theta, phi = np.pi * (0.15 + 0.7 * v), 2.5 * u + 0.4 * np.sign(u - 0.45)  # z < 0 on half
    x = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)
    data = {
        lifting: bandelets.encode(x, threshold=0.02, kind="normal-map", lifting=lifting, restore=False)
        for lifting in (True, False)
    }
    header = unpack(data[True])[0]
    assert (header.channels, header.frames, header.lifting) == (3, True, directional.LEVELS)
    quality = {k: psnr(x, bandelets.decode(d), "normal-map") for k, d in data.items()}
    assert abs(quality[True] - quality[False]) < 1.0
    assert quality[True] > 40


def test_lifting_where_it_cannot_apply_is_refused(crease_map, edge_image):
    with pytest.raises(ValueError, match="directional lifting"):
        bandelets.encode(crease_map, threshold=0.01, kind="normal-map", wavelet="haar", lifting=True)
    data = bandelets.encode(edge_image, threshold=0.01, lifting=True)  # an image, on request
    assert unpack(data)[0].lifting == directional.LEVELS
    assert psnr(edge_image, bandelets.decode(data)) > 40
    header, streams = unpack(bandelets.encode(edge_image, threshold=0.01, wavelet="haar"))
    with pytest.raises(FormatError, match="directional lifting"):
        unpack(pack(replace(header, lifting=2), streams))
    header, streams = unpack(data)
    with pytest.raises(FormatError, match="directional levels"):
        unpack(pack(replace(header, lifting=4), streams))
