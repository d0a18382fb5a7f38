"""The compiled fast paths against the slow reference implementations of tests/reference.py.

The reference gives bit-identical results: the same directions and Lagrangians, the same
coding plans, the same files.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import reference
from conftest import straight_edge
from numba import njit

import bandelets
from bandelets.coding import order as layout
from bandelets.coding.image import code_image, new_coders
from bandelets.format import quantizer as quantize
from bandelets.format.fields import TRANSFORMS_1D
from bandelets.format.levels import parts
from bandelets.search import lagrangian
from bandelets.search.basis import best_trees
from bandelets.transform.bandeletize import bandeletize, debandeletize, debandeletize_bins
from bandelets.transform.bandelets import wavelet_coefficients
from bandelets.transform.wavelets import max_levels, subband_slices


@njit(cache=True)
def _compiled_libm(n):
    out = np.zeros((2, n))
    for i in range(1, n):
        out[0, i] = math.lgamma(i)
        out[1, i] = math.log2(i)
    return out


def test_libm_tables_are_the_compiled_calls():
    calls = _compiled_libm(lagrangian._LGAMMA.shape[0])
    np.testing.assert_array_equal(lagrangian._LGAMMA, calls[0])
    np.testing.assert_array_equal(lagrangian._LOG2, calls[1, : lagrangian._LOG2.shape[0]])


def _crease_subbands(size, threshold, transform_1d="alpert2"):
    """Wavelet coefficients of the crease map and the trees the codec chooses for them."""
    from bandelets.samples import crease_normal_map

    x = crease_normal_map(size)
    levels = max_levels(x.shape[:2])
    coefficients = wavelet_coefficients(x, "cdf97", levels)
    return (
        coefficients,
        levels,
        best_trees(coefficients, levels, threshold, "bandelet", transform_1d),
    )


@pytest.mark.parametrize("width", [4, 8, 16, 32])
def test_search_matches_the_reference(width):
    """Every width, with predicted directions and hints (the refined search above 100)."""
    rng = np.random.default_rng(width)
    edge = np.stack([straight_edge(shape=(32, 64), angle_deg=a, blur=0.7) for a in (20, 20)])
    subbands = 0.2 * edge * np.array([1.0, -0.6])[:, None, None] + 0.01 * rng.standard_normal((2, 32, 64))
    cells = (32 // width, 64 // width)
    predicted = rng.integers(-1, 12, cells)
    n_dirs = lagrangian.directions(width)[1].shape[0]
    hints = np.where(rng.random(cells + (4,)) < 0.3, -1, rng.integers(0, n_dirs, cells + (4,)))
    hints[0, 0] = -1  # no hint at all: the coarse scan
    for options in ({}, {"predicted": predicted, "hints": hints}, {"transform_1d": "haar"}):
        fast = lagrangian.best_directions(subbands, width, 0.02, **options)
        slow = reference.best_directions(subbands, width, 0.02, **options)
        np.testing.assert_array_equal(fast[1], slow[1])
        np.testing.assert_array_equal(fast[0], slow[0])
        assert np.any(fast[1] >= 0)


@pytest.mark.parametrize("kind", TRANSFORMS_1D)
def test_bandeletization_and_plans_match_the_reference(kind):
    coefficients, levels, trees = _crease_subbands(128, 0.01, kind)
    shape = coefficients[0].shape
    assert any(np.any(t.leaves()[3] >= 0) for t in trees)
    for index, ((_, _, where), tree) in enumerate(zip(subband_slices(shape, levels), trees, strict=True)):
        band = coefficients[0][where]
        forward = bandeletize(band, tree, kind)
        np.testing.assert_array_equal(forward, reference.bandeletize(band, tree, kind))
        np.testing.assert_array_equal(
            debandeletize(forward, tree, kind), reference.debandeletize(forward, tree, kind)
        )
        bins = quantize.quantize(forward, 0.003).astype(np.int64)
        expected = bins.copy()
        reference.debandeletize_bins(expected, tree, 0.003, kind)
        debandeletize_bins(bins, tree, 0.003, kind)
        np.testing.assert_array_equal(bins, expected)
        for fast, slow in zip(
            layout.subband_plan(shape, levels, index, tree, kind),
            reference.subband_plan(shape, levels, index, tree, kind),
            strict=True,
        ):
            for field in ("order", "classes", "neighbours"):
                np.testing.assert_array_equal(getattr(fast, field), getattr(slow, field))
    approximation = layout.approximation_plan(shape, levels)
    np.testing.assert_array_equal(
        approximation.neighbours, reference.approximation_plan(shape, levels).neighbours
    )


def test_quantizer_matches_the_reference(rng):
    x = rng.standard_normal((40, 30)) * rng.choice([0.01, 1.0, 100.0], (40, 30))
    x[0, :4] = [0.0, -0.0, 0.5, -0.5]  # the dead zone's edge
    for t in (0.5, 1e-3):
        q = quantize.quantize(x, t)
        np.testing.assert_array_equal(q, reference.quantize(x, t))
        np.testing.assert_array_equal(quantize.dequantize(q, t), reference.dequantize(q, t))


@pytest.mark.parametrize(
    "make, options",
    [
        ("crease", {"threshold": 0.01, "kind": "normal-map"}),
        ("crease", {"threshold": 0.003, "kind": "normal-map", "transform_1d": "haar"}),
        ("edge", {"threshold": 0.02}),
    ],
)
def test_files_match_the_reference(make, options, monkeypatch):
    from bandelets.samples import crease_normal_map

    image = crease_normal_map(128) if make == "crease" else straight_edge(96, angle_deg=25, blur=1.0)
    fast = bandelets.encode(image, **options)
    with reference.patched(monkeypatch):
        slow = bandelets.encode(image, **options)
        slow_decoded = bandelets.decode(fast)
    assert fast == slow
    np.testing.assert_array_equal(bandelets.decode(fast), slow_decoded)


def test_decoded_trees_cache_the_leaves_they_would_find():
    from bandelets.format.header import unpack
    from bandelets.samples import crease_normal_map

    # Without the directional lifting, which leaves the bandelet search nothing to take here.
    data = bandelets.encode(crease_normal_map(64), threshold=0.01, kind="normal-map", lifting=False)
    header, streams = unpack(data)
    trees, _, _ = code_image(new_coders(parts(streams, header.segments)), header)
    assert any(np.any(t.leaves()[3] >= 0) for t in trees)
    for tree in trees:
        for cached, found in zip(tree.leaves(), tree.find_leaves(), strict=True):
            np.testing.assert_array_equal(cached, found)
            assert cached.dtype == found.dtype
