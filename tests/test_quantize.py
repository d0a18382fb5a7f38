"""The paper's quantizer Q_T (bandelets.format.quantizer)."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.format import quantizer as quantize_module
from bandelets.format.quantizer import bin_index, dequantize, quantization_error, quantize

#: Where a bin is reconstructed, ``(q + R) T``: the paper's Q_T has R = 1/2 (the middle of the
#: bin). The module may move it (a reconstruction biased towards zero suits Laplacian
#: coefficients); whatever it is, it must lie inside the bin.
R = getattr(quantize_module, "RECONSTRUCTION", 0.5)


def test_reconstruction_point_is_inside_the_bin():
    assert 0.0 < R < 1.0


def test_reconstruction_is_the_reconstruction_point_of_the_bin():
    t = 0.3
    x = np.array([0.31, 0.59, 0.61, -0.95, 3.0 * 7.3])
    q = np.array([1, 1, 2, -3, 73])
    np.testing.assert_allclose(q_t(x, t), np.sign(q) * (np.abs(q) + R) * t, rtol=1e-12)


def q_t(x, t):
    return dequantize(quantize(np.asarray(x, np.float64), t), t)


@pytest.mark.parametrize("t", [0.25, 0.1, 3.0])
def test_dead_zone(t, rng):
    x = rng.uniform(-t, t, 1000)
    x[:4] = [t, -t, 0.0, -0.0]  # the edges of the dead zone are in it
    assert np.all(quantize(x, t) == 0)
    assert np.all(q_t(x, t) == 0)


@pytest.mark.parametrize("t", [0.25, 0.1, 3.0])
def test_bins_reconstruct_inside_the_bin(t, rng):
    q = rng.integers(1, 50, 2000)
    frac = rng.uniform(0.001, 0.999, q.shape)
    x = (q + frac) * t  # q T <= |x| < (q + 1) T, away from the bin edges
    sign = rng.choice([-1.0, 1.0], q.shape)
    x *= sign
    got = q_t(x, t)
    np.testing.assert_allclose(got, sign * (q + R) * t, rtol=1e-12)
    assert quantize(x, t).dtype == np.int32
    np.testing.assert_array_equal(quantize(x, t), (sign * q).astype(np.int32))


def test_bin_edges_exact():
    t = 0.5  # exactly representable: q T is exact
    x = np.array([1.0, 1.5, 2.0, 0.5000001, -1.0, -1.5, 1.4999999])
    # |x| = T is the dead zone; 2T starts bin 2; just above T is bin 1.
    np.testing.assert_array_equal(quantize(x, t), [2, 3, 4, 1, -2, -3, 2])
    np.testing.assert_allclose(q_t(x, t), (np.array([2, 3, 4, 1, -2, -3, 2]) + 0.0) * t + np.sign(x) * R * t)


@pytest.mark.parametrize("t", [0.25, 0.1, 3.0])
def test_error_bounds_and_symmetry(t, rng):
    x = rng.standard_normal(5000) * 20 * t
    err = np.abs(x - q_t(x, t))
    outside = np.abs(x) > t
    # T / 2 for the paper's Q_T (R = 1/2).
    assert np.all(err[outside] <= max(R, 1 - R) * t * (1 + 1e-12))
    assert np.all(err[~outside] <= t)
    np.testing.assert_array_equal(quantize(-x, t), -quantize(x, t))
    np.testing.assert_array_equal(q_t(-x, t), -q_t(x, t))


def test_dequantize_of_zero_and_shape():
    q = np.array([[0, 1], [-2, 0]], np.int32)
    np.testing.assert_allclose(dequantize(q, 2.0), [[0.0, 2.0 * (1 + R)], [-2.0 * (2 + R), 0.0]])


def test_too_small_threshold_is_a_value_error():
    with pytest.raises(ValueError, match="too small"):
        quantize(np.array([1e6]), 1e-6)


@pytest.mark.parametrize("t", [0.25, 0.1, 3.0])
def test_scalar_helpers_agree_with_array_functions(t, rng):
    x = np.concatenate([rng.standard_normal(500) * 10 * t, [t, -t, 0.0, 2 * t, -3 * t]])
    q = quantize(x, t)
    expected_error = (x - dequantize(q, t)) ** 2
    for value, qi, e in zip(x, q, expected_error, strict=True):
        assert bin_index(float(value), t) == abs(int(qi))
        assert quantization_error(float(value), t) == pytest.approx(e, rel=1e-9, abs=1e-15)
