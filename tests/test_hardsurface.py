"""The default effort's guess of the hard-surface variant (issue 37, :mod:`bandelets.codec.hardsurface`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import bandelets
from bandelets.codec import hardsurface
from bandelets.codec.options import DEFAULT_EFFORT, EncodeOptions
from bandelets.codec.variants import VARIANTS_FROM
from bandelets.samples import bevel_normal_map

NORMAL = EncodeOptions(kind="normal-map")


def _slats(size: int = 64) -> np.ndarray:
    """Louvre slats: a profile down the rows, constant along them, in 8-bit samples' values."""
    tilt = np.rint(np.sin(np.arange(size) * 2 * np.pi / 16) * 60) / 127.5
    vectors = np.zeros((size, size, 3))
    vectors[..., 1] = tilt[:, None]
    vectors[..., 2] = np.sqrt(1.0 - vectors[..., 1] ** 2)
    return vectors


def test_run_fractions_count_windows_of_equal_samples_along_each_axis():
    rows, columns = hardsurface.run_fractions(_slats())
    assert rows == 1.0 and columns == 0.0
    rows, columns = hardsurface.run_fractions(np.transpose(_slats(), (1, 0, 2)))
    assert rows == 0.0 and columns == 1.0
    image = np.zeros((16, 16, 3))
    image[:, 3] = 1.0  # one column apart: a row of 16 has 16 - 8 + 1 windows, 5 of them clear of it
    assert hardsurface.run_fractions(image, run=8)[0] == pytest.approx(5 / 9)
    assert hardsurface.run_fractions(np.zeros((4, 4, 3)), run=8) == (0.0, 0.0)  # too small for a run
    for unusable in (np.zeros((64, 64)), np.zeros((64, 64, 1)), np.zeros(5)):  # refused after, by the checks
        assert hardsurface.run_fractions(unusable) == (0.0, 0.0)


def test_the_guess_is_slats_not_plates_nor_texture():
    assert hardsurface.wants_haar_along_directions(_slats())
    rng = np.random.default_rng(1)
    assert not hardsurface.wants_haar_along_directions(rng.normal(size=(64, 64, 3)))
    plates = bevel_normal_map(256).astype(np.float64) / 127.5 - 1.0  # runs in both axes alike
    rows, columns = hardsurface.run_fractions(plates)
    assert min(rows, columns) > hardsurface.MOST_RUNS
    assert not hardsurface.wants_haar_along_directions(plates)


def test_with_guess_sets_the_variant_only_where_the_highest_effort_would_try_it():
    slats = _slats()
    guessed = hardsurface.with_guess(slats, NORMAL, tiled=False)
    assert (guessed.transform_1d, guessed.lifting) == ("haar", True)
    assert hardsurface.with_guess(np.zeros((64, 64, 3)), NORMAL, tiled=False) == NORMAL
    assert hardsurface.with_guess(slats, NORMAL, tiled=True) == NORMAL
    for changed in (
        {"effort": VARIANTS_FROM},
        {"kind": "image"},
        {"transform_1d": "haar"},
        {"lifting": False},
        {"wavelet": "haar"},
        {"transform": "wavelet"},
    ):
        options = replace(NORMAL, **changed)
        assert hardsurface.with_guess(slats, options, tiled=False) == options, changed


def test_the_default_effort_codes_slats_as_the_variant_would():
    slats = _slats()
    assert NORMAL.effort == DEFAULT_EFFORT
    data = bandelets.encode(slats, bpp=0.5, kind="normal-map", depth=8)
    variant = bandelets.encode(slats, bpp=0.5, kind="normal-map", depth=8, transform_1d="haar", lifting=True)
    assert data == variant
    assert bandelets.decode(data).shape == slats.shape
