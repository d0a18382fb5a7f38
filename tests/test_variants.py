"""The highest effort's trial of the hard-surface choices (issue 37, :mod:`bandelets.codec.variants`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import bandelets
from bandelets.codec import variants
from bandelets.codec.at_threshold import Encoded
from bandelets.codec.options import EncodeOptions
from bandelets.format.header import unpack
from bandelets.metrics import psnr
from bandelets.samples import bevel_normal_map

NORMAL = EncodeOptions(kind="normal-map", effort=variants.VARIANTS_FROM)


def test_applies_to_untouched_normal_maps_at_the_highest_effort_only():
    assert variants.applies(NORMAL, tiled=False)
    assert not variants.applies(NORMAL, tiled=True)
    assert not variants.applies(replace(NORMAL, effort=variants.VARIANTS_FROM - 1), tiled=False)
    for changed in (
        {"kind": "image"},
        {"transform_1d": "haar"},
        {"lifting": False},
        {"wavelet": "haar"},
        {"transform": "wavelet"},
    ):
        assert not variants.applies(replace(NORMAL, **changed), tiled=False), changed


def _fake(results):
    """An ``encode`` that records the options of each call and returns the next of ``results``."""
    calls = []

    def encode(array, options, *, bpp, measured, **targets):
        calls.append(options)
        size, quality, sse, threshold = results[len(calls) - 1]
        return Encoded(b"x" * size, threshold, sse, psnr=quality)

    return calls, encode


def test_each_variant_is_coded_one_effort_below_and_the_best_kept():
    image = np.zeros((8, 8, 3))
    calls, encode = _fake([(100, 40.0, 1.0, 0.1), (99, 41.0, 1.0, 0.1)])
    best = variants.best_of_variants(image, NORMAL, encode, bpp=1.0, measured=False, threshold=None)
    assert len(calls) == len(variants.VARIANTS) == 2
    assert all(c.effort == variants.VARIANTS_FROM - 1 for c in calls)  # no trial inside the trial
    assert (calls[1].transform_1d, calls[1].lifting) == ("haar", True)
    assert best.psnr == 41.0  # a rate target: the better PSNR
    calls, encode = _fake([(100, 40.0, 1.0, 0.1), (120, 40.0, 1.0, 0.1)])
    best = variants.best_of_variants(
        image, NORMAL, encode, bpp=None, measured=False, psnr=40.0, threshold=None
    )
    assert len(best.data) == 100  # a quality target: the smaller file
    calls, encode = _fake([(100, 40.0, 5.0, 0.1), (120, 40.0, 1.0, 0.1)])
    best = variants.best_of_variants(image, NORMAL, encode, bpp=None, measured=False, threshold=0.1)
    assert len(best.data) == 120  # a threshold: the smaller Lagrangian (4 less error for 160 bits)


@pytest.fixture(scope="module")
def bevel():
    return bevel_normal_map(64)


def test_the_highest_effort_decodes_at_least_as_well_as_the_one_below(bevel, monkeypatch):
    reference = bevel.astype(np.float64) / 255.0 * 2.0 - 1.0
    below = bandelets.encode(bevel, bpp=1.0, kind="normal-map", effort=variants.VARIANTS_FROM - 1)
    calls = []
    trial = variants.best_of_variants
    monkeypatch.setattr(variants, "best_of_variants", lambda *a, **k: calls.append(a) or trial(*a, **k))
    best = bandelets.encode(bevel, bpp=1.0, kind="normal-map", effort=variants.VARIANTS_FROM)
    assert len(calls) == 1  # the encoder's front door tried the variants, once
    assert len(best) <= 64 * 64 / 8
    quality = [psnr(reference, bandelets.decode(d), "normal-map") for d in (below, best)]
    assert quality[1] >= quality[0] - 1e-9  # the file below is one of the files tried
    header = unpack(best)[0]
    assert header.transform_1d in ("alpert2", "haar")
