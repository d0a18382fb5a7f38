"""PSNR, peaks and BD-PSNR (bandelets.metrics)."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.metrics import angular_error, bd_psnr, bits_per_pixel, peak, psnr
from bandelets.transform import normals
from bandelets.transform.normals import unit_vectors, with_z


def test_psnr_of_a_uniform_error(rng):
    ref = rng.random((32, 40))
    ref[0, 0], ref[-1, -1] = 0.0, 2.0  # value range exactly 2
    decoded = ref + 0.02 * rng.choice([-1.0, 1.0], ref.shape)  # RMSE exactly 0.02
    assert psnr(ref, decoded) == pytest.approx(20 * np.log10(2.0 / 0.02), abs=1e-9)
    assert psnr(ref, decoded) == pytest.approx(40.0, abs=1e-9)


def test_psnr_identical_is_inf(rng):
    ref = rng.random((8, 8, 3))
    assert psnr(ref, ref.copy()) == float("inf")


def test_psnr_of_a_constant_reference_uses_peak_one():
    ref = np.full((4, 4), 5.0)
    assert peak(ref) == 1.0
    assert psnr(ref, ref + 0.1) == pytest.approx(20.0, abs=1e-9)


def test_psnr_accepts_a_flat_decoded_array(rng):
    ref = rng.random((6, 5))
    dec = ref + 0.01
    assert psnr(ref, dec.ravel()) == pytest.approx(psnr(ref, dec))


def test_normal_map_psnr_renormalises_both_maps(rng):
    n = rng.standard_normal((16, 16, 3))
    n[..., 2] = np.abs(n[..., 2]) + 0.5
    unit = n / np.linalg.norm(n, axis=-1, keepdims=True)
    scaled = 3.0 * n  # not unit length: the metric must renormalise it
    decoded = unit + 0.01 * rng.standard_normal(unit.shape)
    turned = decoded / np.linalg.norm(decoded, axis=-1, keepdims=True)
    expected = 20 * np.log10(np.max(np.abs(unit)) / np.sqrt(np.mean((unit - turned) ** 2)))
    # A decoded map read back from samples is not of unit length either: only directions count.
    assert psnr(scaled, 0.9 * decoded, "normal-map") == pytest.approx(expected, abs=1e-9)
    assert psnr(scaled, unit, "normal-map") > 250  # equal up to rounding
    assert peak(unit, "normal-map") == pytest.approx(np.max(np.abs(unit)))
    # As an image, the same arrays compare differently (different peak, no renormalisation).
    assert psnr(scaled, decoded, "image") != pytest.approx(expected, abs=0.1)


def test_geometry_image_peak_is_the_bounding_box_diagonal():
    positions = np.zeros((2, 2, 3))
    positions[1, 1] = [3.0, 4.0, 12.0]
    assert peak(positions, "geometry-image") == pytest.approx(13.0)


def test_unit_vectors_and_zero_vectors():
    v = np.array([[3.0, 0.0, 4.0], [0.0, 0.0, 0.0]])
    u = unit_vectors(v)
    np.testing.assert_allclose(u, [[0.6, 0.0, 0.8], [0.0, 0.0, 1.0]])
    assert not np.shares_memory(u, v)


def test_bits_per_pixel():
    assert bits_per_pixel(100, (20, 40)) == 1.0
    assert bits_per_pixel(100, (20, 40, 3)) == 1.0


RATES = [0.25, 0.5, 1.0, 2.0, 4.0]
PSNRS = [28.1, 31.7, 35.0, 38.6, 41.9]


def test_bd_psnr_of_a_curve_against_itself_is_zero():
    assert bd_psnr(RATES, PSNRS, RATES, PSNRS) == pytest.approx(0.0, abs=1e-9)


def test_bd_psnr_of_a_shifted_curve():
    up = [p + 1.0 for p in PSNRS]
    assert bd_psnr(RATES, up, RATES, PSNRS) == pytest.approx(1.0, abs=1e-9)
    assert bd_psnr(RATES, PSNRS, RATES, up) == pytest.approx(-1.0, abs=1e-9)


def test_bd_psnr_integrates_over_the_common_rate_range():
    # Both curves sample the same cubic in log10(rate); B over a wider range.
    def curve(r):
        x = np.log10(r)
        return 35 + 8 * x - x**2 + 0.5 * x**3

    rates_a = np.array([0.5, 1.0, 2.0, 4.0])
    rates_b = np.array([0.1, 0.3, 1.0, 3.0, 8.0])
    gain = bd_psnr(rates_a, curve(rates_a) + 0.5, rates_b, curve(rates_b))
    assert gain == pytest.approx(0.5, abs=1e-9)


def test_bd_psnr_without_overlap_is_a_value_error():
    with pytest.raises(ValueError, match="overlap"):
        bd_psnr([1, 2, 3, 4], PSNRS[:4], [5, 6, 7, 8], PSNRS[:4])


def test_angular_error_of_known_rotations(rng):
    normals = unit_vectors(rng.normal(size=(20, 10, 3)))
    angles = np.full((20, 10), 2.0)
    angles[0, 0] = 30.0  # one pixel far off: the max, not the 99th percentile (1 of 200)
    # Turn each normal by its angle about an axis perpendicular to it.
    axis = unit_vectors(np.cross(normals, rng.normal(size=normals.shape)))
    t = np.radians(angles)[..., None]
    turned = normals * np.cos(t) + np.cross(axis, normals) * np.sin(t)
    error = angular_error(normals, 3.0 * turned)  # lengths do not count
    assert error.max == pytest.approx(30.0, abs=1e-9)
    assert error.p99 == pytest.approx(np.percentile(angles, 99), abs=1e-9)
    assert error.mean == pytest.approx(angles.mean(), abs=1e-9)
    assert angular_error(normals, normals).max < 1e-5  # atan2: no arccos noise near 0


def test_angular_error_of_xy_maps_rebuilds_z():
    xy = np.array([[[0.6, 0.0], [0.0, 0.0]]])
    assert np.allclose(with_z(xy), [[[0.6, 0.0, 0.8], [0.0, 0.0, 1.0]]])
    error = angular_error(xy, [[[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]])
    assert error.max == pytest.approx(np.degrees(np.arcsin(0.6)))
    with pytest.raises(ValueError, match="one shape"):
        angular_error(np.ones((2, 2, 3)), np.ones((2, 3, 3)))


@pytest.mark.parametrize("channels", [2, 3])
def test_unit_normals_are_the_unit_vectors_of_the_decoded_channels(channels, rng):
    from bandelets.transform.normals import unit_normals

    padded = rng.uniform(-1.2, 1.2, (channels, 12, 15))  # some x, y outside the unit disc
    padded[:, 0, 0] = 0.0  # a zero vector (with three channels) turns to +z
    padded[:, -1, -1] = np.nan  # in the padding: not returned, not checked
    got = unit_normals(padded, 10, 13)
    box = np.moveaxis(padded[:, :10, :13], 0, -1)
    expected = unit_vectors(with_z(box) if channels == 2 else box)
    assert got.shape == (10, 13, 3)
    np.testing.assert_allclose(got, expected, rtol=0, atol=4e-16)
    np.testing.assert_allclose(np.linalg.norm(got, axis=-1), 1.0, atol=1e-15)
    padded[1, 3, 4] = np.inf
    assert unit_normals(padded, 10, 13) is None


@pytest.mark.parametrize("equidistant", [False, True])
def test_unit_normals_of_a_large_map_in_two_threads_are_the_same_numbers(monkeypatch, rng, equidistant):
    """Above ``THREADED_PIXELS`` (and on more than one core) the two halves of the rows are made in
    two threads; float32 channels (the restored ones) are read as their float64 copy: the same
    numbers, and a value that is not finite is found in either half."""
    from bandelets import metrics

    padded = rng.uniform(-1.2, 1.2, (2, 40, 30)).astype(np.float32)
    whole = normals.unit_normals(padded.astype(np.float64), 37, 29, equidistant)
    monkeypatch.setattr(metrics, "CORES", 2)
    monkeypatch.setattr(metrics, "THREADED_PIXELS", 0)
    np.testing.assert_array_equal(normals.unit_normals(padded, 37, 29, equidistant), whole)
    for row in (3, 30):
        broken = padded.copy()
        broken[0, row, 5] = np.nan
        assert normals.unit_normals(broken, 37, 29, equidistant) is None


def test_equidistant_coordinates_invert_and_stop_at_minus_z(rng):
    from bandelets.transform.normals import equidistant, unit_normals

    normals = unit_vectors(rng.normal(size=(9, 11, 3)))  # every way, some below the horizon
    normals[0, 0] = [0.0, 0.0, 1.0]  # the pole, where x, y / |x, y| is undefined
    coded = np.moveaxis(equidistant(normals), -1, 0)
    # The length of the coordinates is the angle to +z.
    np.testing.assert_allclose(np.hypot(*coded), np.arccos(np.clip(normals[..., 2], -1, 1)), atol=1e-7)
    np.testing.assert_allclose(unit_normals(coded, 9, 11, equidistant=True), normals, atol=1e-12)
    # Longer than pi (decoded noise): the vector stops at -z rather than wrap around.
    beyond = unit_normals(np.array([[[4.0]], [[0.0]]]), 1, 1, equidistant=True)
    np.testing.assert_allclose(beyond[0, 0], [0.0, 0.0, -1.0], atol=1e-15)


def test_the_encoders_measure_sums_two_halves_of_a_large_map_as_one(monkeypatch):
    """Above ``THREADED_PIXELS`` the measure of a normal map sums the halves of its rows in two
    threads: the PSNR of the whole, as in one pass (to the last bits of the sum's order)."""
    from bandelets import metrics

    rng = np.random.default_rng(3)
    reference = unit_vectors(rng.normal(size=(300, 280, 3)) + [0.0, 0.0, 4.0])
    decoded = normals.equidistant(unit_vectors(reference + rng.normal(scale=0.01, size=reference.shape)))
    channels = np.ascontiguousarray(np.moveaxis(decoded, -1, 0))
    monkeypatch.setattr(metrics, "CORES", 2)
    halves = metrics.psnr_of_channels(reference, "normal-map", 8, equidistant=True)(channels)
    monkeypatch.setattr(metrics, "THREADED_PIXELS", 10**9)
    whole = metrics.psnr_of_channels(reference, "normal-map", 8, equidistant=True)(channels)
    assert 20.0 < whole < 80.0
    assert halves == pytest.approx(whole, abs=1e-9)


@pytest.mark.parametrize("equidistant", [False, True])
def test_the_encoders_measure_reads_float32_channels_as_their_float64_copy(equidistant):
    """The restored channels are float32: the measure reads them without a float64 copy, to the
    same last bit as the copy (each value widened exactly before any arithmetic)."""
    from bandelets import metrics

    rng = np.random.default_rng(4)
    reference = unit_vectors(rng.normal(size=(20, 30, 3)) + [0.0, 0.0, 3.0])
    channels = (0.3 * rng.normal(size=(2, 20, 30))).astype(np.float32)
    measure = metrics.psnr_of_channels(reference, "normal-map", equidistant=equidistant)
    assert measure(channels) == measure(channels.astype(np.float64))
