"""The encoder's choice of the count of wavelet levels (bandelets.levelchoice, wavelets.coarse_blocks)."""

from __future__ import annotations

import numpy as np
import pytest

import bandelets
from bandelets import encoder, metrics, normalmaps
from bandelets.bitstream import unpack
from bandelets.files import from_samples
from bandelets.levelchoice import MIN_LEVELS, choose_levels
from bandelets.samples import bevel_normal_map, bump_normal_map
from bandelets.transform import wavelet_coefficients
from bandelets.wavelets import coarse_blocks, max_levels, wavedec


@pytest.mark.parametrize("first", [1, 2, 5])
def test_coarse_blocks_are_the_coarse_part_of_each_transform(first, rng):
    x = rng.standard_normal((96, 128)).cumsum(0).cumsum(1)
    blocks = coarse_blocks(wavedec(x, "cdf97", 5), 5, first)
    assert sorted(blocks) == list(range(first, 6))
    for levels, block in blocks.items():
        expected = wavedec(x, "cdf97", levels)[: 96 >> first, : 128 >> first]
        np.testing.assert_allclose(block, expected, rtol=0, atol=1e-9 * np.abs(expected).max())


def _coded(vectors):
    x = metrics.unit_vectors(vectors)
    return normalmaps.equidistant(x), max_levels(x.shape[:2])


def test_flat_facets_take_fewer_levels_smooth_bumps_all():
    bevel, levels = _coded(from_samples(bevel_normal_map(128), "normal-map", 8))
    assert choose_levels(wavelet_coefficients(bevel, "cdf97", levels), levels, 0.3) == MIN_LEVELS
    bumps, levels = _coded(np.asarray(bump_normal_map(128), np.float64))
    assert choose_levels(wavelet_coefficients(bumps, "cdf97", levels), levels, 0.06) == levels


def test_the_encoder_writes_the_levels_chosen_and_they_pay(monkeypatch):
    samples = bevel_normal_map(128)
    reference = metrics.unit_vectors(from_samples(samples, "normal-map", 8))
    files = {}
    for choice in ("chosen", "all levels"):
        if choice == "all levels":
            monkeypatch.setattr(encoder, "choose_levels", lambda coefficients, levels, threshold, frames=False: levels)
        data = bandelets.encode(samples, bpp=0.5, kind="normal-map", depth=8)
        assert 8 * len(data) <= 0.5 * 128 * 128
        files[choice] = unpack(data)[0].levels, metrics.psnr(reference, bandelets.decode(data), "normal-map")
    assert files["chosen"][0] == MIN_LEVELS
    assert files["all levels"][0] == max_levels((128, 128))
    assert files["chosen"][1] > files["all levels"][1] + 0.3
