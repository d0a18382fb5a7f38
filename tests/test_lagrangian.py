"""The Lagrangian of a square, the best direction search, and the rate model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import straight_edge

import bandelets
from bandelets.coding.image import code_image, new_coders
from bandelets.format.header import Header
from bandelets.format.quantizer import dequantize, quantize
from bandelets.search.basis import best_trees
from bandelets.search.lagrangian import (
    LAMBDA,
    RATE_MODEL,
    best_directions,
    coefficient_bits,
    geometry_bits,
    square_features,
)
from bandelets.transform.bandeletize import bandeletize, transform_rows
from bandelets.transform.bandelets import apply_trees, wavelet_coefficients
from bandelets.transform.geometry import directions
from bandelets.transform.wavelets import max_levels, subband_slices

# ---------------------------------------------------------------------------------------------
# The pieces of the Lagrangian.


def test_square_features_of_a_wavelet_square():
    t = 0.5
    values = np.array([0.0, 2.6, -1.2, 0.4, 0.5, -7.1])  # bins 0, 5, -2, 0, 0 (edge), -14
    significance, count, magnitude, distortion = square_features(values, t, 0)
    assert count == 3
    assert significance == pytest.approx(math.log2(math.comb(6, 3)))
    assert magnitude == pytest.approx(math.log2(5) + math.log2(2) + math.log2(14))
    expected = np.sum((values - dequantize(quantize(values, t), t)) ** 2)
    assert distortion == pytest.approx(expected)


def test_square_features_group_1d_scales():
    """For a bandelet square each 1D scale [0, k), [k, 2k), [2k, 4k), ... is its own group."""
    t = 1.0
    values = np.zeros(16)
    values[[0, 2, 3, 5, 9, 10, 11]] = 3.0
    k = 2  # groups [0,2) [2,4) [4,8) [8,16): significant 1, 2, 1, 3
    significance, count, _, _ = square_features(values, t, k)
    assert count == 7
    expected = math.log2(2) + 0 + math.log2(math.comb(4, 1)) + math.log2(math.comb(8, 3))
    assert significance == pytest.approx(expected)


def test_coefficient_bits_use_the_model():
    t = 0.25
    values = np.random.default_rng(0).standard_normal(64)
    for k, base in [(0, 0), (2, 3)]:
        s, n, m, d = square_features(values, t, k)
        distortion, bits = coefficient_bits(values, t, k, RATE_MODEL)
        assert distortion == pytest.approx(d)
        a, b, c = RATE_MODEL[base : base + 3]
        assert bits == pytest.approx(a * s + b * n + c * m)


def _lagrangians(square_channels, t, width, transform_1d="alpert2"):
    """Direct evaluation of L(S, NULL) and L(S, d) for every direction (no prediction)."""
    price = LAMBDA * t * t
    null_bits, direction_bits = geometry_bits(width)
    k = 2 if transform_1d == "alpert2" else 1
    null = price * null_bits
    for s in square_channels:
        d, b = coefficient_bits(s.ravel(), t, 0, RATE_MODEL)
        null += d + price * b
    out = []
    for order in directions(width)[1]:
        total = price * direction_bits
        for s in square_channels:
            coeffs = transform_rows(s.ravel()[order][None, :], transform_1d)[0]
            d, b = coefficient_bits(coeffs, t, k, RATE_MODEL)
            total += d + price * b
        out.append(total)
    return null, np.array(out)


@pytest.mark.parametrize("transform_1d", ["alpert2", "haar"])
def test_best_directions_minimises_the_lagrangian(transform_1d):
    width, t = 4, 0.05
    # Two channels with a shared oblique edge plus noise, one square per 4 x 4 block.
    edge = straight_edge(shape=(8, 12), angle_deg=35, blur=0.8)
    rng = np.random.default_rng(1)
    subbands = np.stack([edge, -0.5 * edge]) + 0.01 * rng.standard_normal((2, 8, 12))
    cost, best = best_directions(subbands, width, t, transform_1d=transform_1d)
    assert cost.shape == best.shape == (2, 3)
    found_direction = False
    for r in range(2):
        for c in range(3):
            square = subbands[:, 4 * r : 4 * r + 4, 4 * c : 4 * c + 4]
            null, per_direction = _lagrangians(square, t, width, transform_1d)
            expected = min(null, per_direction.min())
            assert cost[r, c] == pytest.approx(expected, rel=1e-9)
            if best[r, c] >= 0:
                found_direction = True
                assert per_direction[best[r, c]] == pytest.approx(expected, rel=1e-9)
                assert per_direction[best[r, c]] < null
            else:
                assert null <= per_direction.min()
    assert found_direction


def test_null_only_and_quiet_squares():
    rng = np.random.default_rng(2)
    subbands = rng.standard_normal((1, 16, 16))
    cost, best = best_directions(subbands, 8, 0.1, allow_directions=False)
    assert np.all(best == -1)
    for r in range(2):
        for c in range(2):
            null, _ = _lagrangians(subbands[:, 8 * r : 8 * r + 8, 8 * c : 8 * c + 8], 0.1, 8)
            assert cost[r, c] == pytest.approx(null, rel=1e-9)
    # Squares of energy below T**2 quantize to zero in any basis: NULL, at its geometry price.
    quiet = 0.01 * rng.standard_normal((3, 8, 8))
    cost, best = best_directions(quiet, 4, 0.5)
    assert np.all(best == -1)
    assert np.allclose(
        cost, np.sum(quiet.reshape(3, 2, 4, 2, 4) ** 2, axis=(0, 2, 4)) + LAMBDA * 0.25 * geometry_bits(4)[0]
    )


# ---------------------------------------------------------------------------------------------
# (1) Directions follow a straight edge.


def _angle_error_deg(a, b):
    """Distance between two orientations (angles modulo pi), in degrees."""
    return float(np.rad2deg(abs((a - b + np.pi / 2) % np.pi - np.pi / 2)))


@pytest.mark.parametrize("angle_deg", [30.0, 120.0])
def test_directions_follow_a_straight_edge(angle_deg):
    size, blur = 128, 1.5
    x = straight_edge(size, angle_deg=angle_deg, blur=blur)
    b = bandelets.forward(x, 0.02)
    theta = np.deg2rad(angle_deg)
    errors = []
    bands = subband_slices(b.coefficients.shape, b.levels)
    for (level, _, _), tree in zip(bands, b.trees, strict=True):
        for r, c, w, d in zip(*tree.leaves(), strict=True):
            if d < 0:
                continue
            # Every bandelet square lies along the edge: its footprint in the image (a square
            # of side w 2**level) is within the wavelet support around the line.
            scale = 2**level
            cy, cx = (r + w / 2) * scale, (c + w / 2) * scale
            dx, dy = cx - size / 2 + 0.3, cy - size / 2 + 0.2
            distance = abs(-np.sin(theta) * dx + np.cos(theta) * dy)
            assert distance < (w / np.sqrt(2) + 4) * scale + 4 * blur, (level, r, c, w)
            if level == 1:
                errors.append(_angle_error_deg(directions(int(w))[0][d], theta))
    errors = np.array(errors)
    assert len(errors) >= 8, "the finest subbands should bandeletize the edge"
    # The chosen angle is within a few degrees of the edge for most squares.
    assert np.mean(errors <= 6.0) > 0.6, np.sort(errors)
    assert np.median(errors) <= 3.0


def test_no_directions_inside_a_smooth_image():
    # (The image border, where the symmetric extension puts a kink, may get some.)
    y, x = np.mgrid[0:64, 0:64] / 64.0
    b = bandelets.forward(np.sin(2 * x) + y**2, 0.02)
    for (_, _, (rows, cols)), tree in zip(
        subband_slices(b.coefficients.shape, b.levels), b.trees, strict=True
    ):
        h, w = rows.stop - rows.start, cols.stop - cols.start
        for r, c, width, d in zip(*tree.leaves(), strict=True):
            if 0 < r and r + width < h and 0 < c and c + width < w:
                assert d == -1


# ---------------------------------------------------------------------------------------------
# (2) The rate model tracks the real coder.


def _model_and_actual_bits(image, kind, transform_1d, thresholds):
    """Per threshold, modelled and actual bits of the wavelet squares (NULL leaves of the
    wavelet transform), as in benchmarks/calibrate_rate.py."""
    levels = max_levels(image.shape[:2])
    coefficients = wavelet_coefficients(image, "cdf97", levels)
    model = actual = 0.0
    for t in thresholds:
        header = Header(
            height=image.shape[0],
            width=image.shape[1],
            channels=image.shape[2],
            kind=kind,
            transform="wavelet",
            wavelet="cdf97",
            levels=levels,
            threshold=t,
            depth=0,
            transform_1d=transform_1d,
        )
        trees = best_trees(coefficients, levels, t, "wavelet", transform_1d)
        bands = [apply_trees(c, levels, trees, bandeletize, transform_1d) for c in coefficients]
        quantized = [quantize(b, t).ravel() for b in bands]
        _, _, spent = code_image(new_coders(), header, trees, quantized)
        for b, bits in zip(bands, spent, strict=True):
            bits = bits.reshape(b.shape)
            for (_, _, where), tree in zip(subband_slices(b.shape, levels), trees, strict=True):
                for r, c, w, d in zip(*tree.leaves(), strict=True):
                    assert d < 0
                    square = (
                        slice(where[0].start + r, where[0].start + r + w),
                        slice(where[1].start + c, where[1].start + c + w),
                    )
                    model += coefficient_bits(b[square].ravel(), t, 0, RATE_MODEL)[1]
                    actual += bits[square].sum()
    return model, actual


def test_rate_model_tracks_the_coder(crease_map):
    thresholds = [0.04, 0.02, 0.01, 0.005]
    model, actual = _model_and_actual_bits(crease_map, "normal-map", "alpert2", thresholds)
    assert actual > 1000
    assert abs(model / actual - 1) < 0.15, (model, actual)


def test_coder_ledger_matches_the_file_size(crease_map):
    """The ledger the rate model is fitted to is the real cost: its total is the size of the
    coefficient stream, up to the coder's flush bytes."""
    t = 0.01
    levels = max_levels(crease_map.shape[:2])
    coefficients = wavelet_coefficients(crease_map, "cdf97", levels)
    header = Header(
        height=64,
        width=64,
        channels=3,
        kind="normal-map",
        transform="bandelet",
        wavelet="cdf97",
        levels=levels,
        threshold=t,
        depth=0,
        transform_1d="alpert2",
    )
    trees = best_trees(coefficients, levels, t, "bandelet", "alpert2")
    bands = [apply_trees(c, levels, trees, bandeletize, "alpert2") for c in coefficients]
    quantized = [quantize(b, t).ravel() for b in bands]
    coders = new_coders()
    _, _, spent = code_image(coders, header, trees, quantized)
    stream = b"".join(coders[2].segments)  # format 19: the segments code_image cut
    total = sum(float(s.sum()) for s in spent)
    assert 8 * len(stream) == pytest.approx(total, rel=0.02, abs=64)
