"""Direction-adaptive lifting: exact inverse, plain CDF 9/7 without directions, the codec's use."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import straight_edge

import bandelets
from bandelets.coding import directions as coding_directions
from bandelets.coding import rangecoder
from bandelets.format.fields import FormatError
from bandelets.format.header import pack, unpack
from bandelets.metrics import psnr
from bandelets.samples import bump_normal_map, crease_normal_map
from bandelets.search import directions
from bandelets.transform import directional, lifting
from bandelets.transform.wavelets import wavedec

_TABLES = (directional.OFFSETS, directional.WEIGHTS, directional.SCALES)


def test_synthesis_inverts_analysis_whatever_the_directions(rng):
    channels = [rng.normal(size=(64, 48)) for _ in range(2)]
    coefficients, fields = directions.chosen_analysis(channels, 3, 2, 0.1)
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
        np.argmin(lifting.direction_costs(diagonal.astype(float), *_TABLES, 8, 0.5)[:, 1:, 1:-1], axis=0)
        == slope_one
    )


def test_directions_pay_on_creases_not_on_smooth_bumps():
    for sample, threshold, expected in ((crease_normal_map, 0.01, True), (bump_normal_map, 0.005, False)):
        channels = list(np.moveaxis(sample(256)[..., :2], -1, 0))
        lifted, fields = directions.chosen_analysis(channels, 6, 2, threshold)
        assert any(np.any(f) for f in fields)  # some block finds a direction, even on the bumps
        assert directions.pays(channels, lifted, fields, 6, 2, threshold) is expected


def test_a_normal_map_is_lifted_by_default_only_where_directions_pay():
    bumps = bump_normal_map(64)
    for requested, expected in ((True, directional.LEVELS), (None, 0), (False, 0)):
        assert (
            unpack(bandelets.encode(bumps, threshold=0.001, kind="normal-map", lifting=requested))[0].lifting
            == expected
        )


def test_an_oblique_edge_leaves_fewer_fine_coefficients():
    x = straight_edge(64, angle_deg=63.0, blur=0.5)
    lifted, fields = directions.chosen_analysis([x], 3, 2, 0.01)
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
    coder = rangecoder.Coder(coding_directions.N_CONTEXTS)
    coding_directions.code_fields(coder, fields, shape, 2, 0)
    decoded = coding_directions.code_fields(
        rangecoder.Coder(coding_directions.N_CONTEXTS, coder.finish()), None, shape, 2, 0
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
    # With the pair codes, one level more where that pays (here).
    assert unpack(data[True])[0].lifting == directional.LEVELS + directions.DEEPER
    assert unpack(data[False])[0].lifting == 0
    # On the small map the directions pay with the pair codes (they did not with the slopes
    # alone): by default the file is lifted, and smaller at the same threshold.
    assert data[None] == data[True]
    assert len(data[True]) < 0.95 * len(data[False])
    quality = {k: psnr(crease_map, bandelets.decode(d), "normal-map") for k, d in data.items()}
    # The same threshold gives about the same quality (the gain, a smaller file for it, shows on
    # larger maps: benchmarks/rd_normal_maps.py).
    assert abs(quality[True] - quality[False]) < 1.0
    assert quality[True] > 40
    # On a larger one they pay: lifted by default (not for an image).
    crease = crease_normal_map(256)
    assert unpack(bandelets.encode(crease, threshold=0.01, kind="normal-map", restore=False))[0].lifting >= 2
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


def _pair_code(steps) -> int:
    return next(i for i, w in enumerate(directional.WEIGHTS) if np.array_equal(w, steps))


@pytest.mark.parametrize("position", [32, 33])
def test_a_step_between_two_flat_facets_at_an_angle_leaves_no_high_pass_in_one_pair_code(position):
    # Two flat facets of a normal map (constant components), the step between them at an angle
    # (two columns further every 8 rows), starting at an even or odd column.
    rows = np.arange(16)[:, None]
    x = np.where(np.arange(64)[None, :] < position + rows // 8 * 2, 0.3, -0.55) + np.zeros((16, 1))
    codes = np.zeros((2, 8), np.int64)
    plain, paired = np.empty_like(x), np.empty_like(x)
    lifting.directional_pass(x, plain, True, codes, *_TABLES, 8)
    assert np.sum(np.abs(plain[:, 32:]) > 1e-3) >= 3 * 16  # CDF 9/7 rings: 3 or 4 per row
    # The pair code that puts the step between two pairs: PAIR_BEFORE for a step at an even
    # column (pairs 2k, 2k + 1), PAIR_AFTER at an odd one.
    steps = directional.PAIR_BEFORE if position % 2 == 0 else directional.PAIR_AFTER
    codes[:] = _pair_code(steps)
    lifting.directional_pass(x, paired, True, codes, *_TABLES, 8)
    np.testing.assert_allclose(paired[:, 32:], 0.0, atol=1e-12)
    # The other one leaves one high-pass sample per row, no more.
    other = directional.PAIR_AFTER if position % 2 == 0 else directional.PAIR_BEFORE
    codes[:] = _pair_code(other)
    lifting.directional_pass(x, paired, True, codes, *_TABLES, 8)
    assert np.all(np.sum(np.abs(paired[:, 32:]) > 1e-3, axis=1) == 1)


def test_pair_codes_meet_cdf97_blocks_without_a_seam_on_a_flat_region():
    # A constant line: whatever the mix of codes, no high-pass sample and the low-pass of CDF 9/7.
    x = np.full((16, 64), 0.7)
    codes = np.array([[0, 13, 14, 0, 14, 13, 13, 0], [13, 0, 14, 7, 0, 13, 14, 14]])
    lifted, plain = np.empty_like(x), np.empty_like(x)
    lifting.directional_pass(x, lifted, True, codes, *_TABLES, 8)
    lifting.cdf97_pass(x, plain, True)
    np.testing.assert_allclose(lifted, plain, atol=1e-12)
    np.testing.assert_allclose(lifted[:, 32:], 0.0, atol=1e-12)


@pytest.mark.parametrize("code", range(len(directional.OFFSETS)))
def test_every_code_is_exactly_inverted_and_as_heavy_as_cdf97(rng, code):
    source = rng.normal(size=(16, 32))
    codes = np.full((2, 4), code, np.int64)
    lifted, back = np.empty_like(source), np.empty_like(source)
    lifting.directional_pass(source, lifted, True, codes, *_TABLES, 8)
    lifting.directional_pass(lifted.copy(), back, False, codes, *_TABLES, 8)
    np.testing.assert_allclose(back, source, atol=1e-12)
    if code in (_pair_code(directional.PAIR_BEFORE), _pair_code(directional.PAIR_AFTER)):
        # A high-pass sample's synthesis has the norm of a CDF 9/7 one (1.0915), away from the ends.
        impulse = np.zeros((16, 32))
        impulse[:, 24] = 1.0
        lifting.directional_pass(impulse, back, False, codes, *_TABLES, 8)
        np.testing.assert_allclose(np.linalg.norm(back[8]), 1.0915052823311142, rtol=1e-12)


def test_pair_codes_are_kept_where_they_pay():
    # A map of flat plates with steps (as an 8-bit map's flat regions): the pairs pay; on the
    # smooth bumps the estimate keeps the slopes alone.
    v, u = np.mgrid[0:128, 0:128]
    plates = [np.where((u + v // 3) % 40 < 20, 0.3, -0.2), np.where((v - u // 4) % 32 < 12, 0.1, 0.5)]
    _, fields, lifted, _ = directions.lift(plates, 5, 2, 0.01)
    assert any(np.any(f >= len(directional.SLOPES_97)) for f in fields)
    assert lifted == 3 and len(fields) == 6  # and one level deeper, where the pairs pay more
    bumps = list(np.moveaxis(bump_normal_map(128)[..., :2], -1, 0))
    _, fields, _, _ = directions.lift(bumps, 5, 2, 0.005)
    assert not any(np.any(f >= len(directional.SLOPES_97)) for f in fields)
