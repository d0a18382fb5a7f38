"""The coarse approximation's coder (bandelets.coding.approximation, format version 18)."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.coding import coefficients
from bandelets.coding.approximation import N_CONTEXTS, code_approximation
from bandelets.coding.order import approximation_plan
from bandelets.coding.rangecoder import Coder, CorruptStream

SHAPE, LEVELS = (128, 96), 2  # an approximation of 32 x 24 bins


def _facets(rng) -> list[np.ndarray]:
    """Two channels of bins, shape (H * W,), constant on facets and jumping at the same edges in
    both (the approximation of a faceted normal map), a little noise on a fifth of them."""
    h, w = SHAPE[0] >> LEVELS, SHAPE[1] >> LEVELS
    rows, cols = np.mgrid[:h, :w]
    facet = (rows + 2 * cols > 30).astype(int) + 2 * (rows > 20)
    channels = []
    for step in (45, -30):
        q = np.zeros(SHAPE, np.int32)
        q[:h, :w] = step * facet + rng.integers(-1, 2, (h, w)) * (rng.random((h, w)) < 0.2)
        channels.append(q.ravel())
    return channels


def _code(channels, decoding_data=None, approximation=True):
    """Code the channels' approximations (the second guided by the first) or decode them from
    ``decoding_data``; returns the bytes or the decoded channels, and the bits spent."""
    plan = approximation_plan(SHAPE, LEVELS)
    size = SHAPE[0] * SHAPE[1]
    n = N_CONTEXTS if approximation else coefficients.coefficient_contexts()
    coder = Coder(n, decoding_data)
    out = [np.zeros(size, np.int32) for _ in channels] if decoding_data is not None else channels
    spent = [np.zeros(size) for _ in channels]
    guides = [np.zeros(0, np.int32)] + out[:-1]
    code = code_approximation if approximation else coefficients.code_coefficients
    for q, guide, bits in zip(out, guides, spent, strict=True):
        code(coder, q, plan, np.zeros(size, np.int64), guide, bits)
    if decoding_data is not None:
        coder.check()
        return out, spent
    return coder.finish(), spent


def test_round_trip_and_prices(rng):
    channels = _facets(rng)
    data, spent = _code(channels)
    total = sum(s.sum() for s in spent)
    assert 8 * len(data) == pytest.approx(total, rel=0.03, abs=64)
    decoded, _ = _code(channels, data)
    for a, b in zip(decoded, channels, strict=True):
        np.testing.assert_array_equal(a, b)


def test_cheaper_than_version_17_where_the_channels_jump_together(rng):
    # The gradient and the guide's residual as contexts: the same bins in fewer bytes than the
    # detail coefficients' class 0 codes them (what version 17 wrote, and the level choice prices).
    channels = _facets(rng)
    ours, _ = _code(channels)
    before, _ = _code(channels, approximation=False)
    assert len(ours) < 0.95 * len(before)


def test_a_cut_stream_is_refused(rng):
    channels = _facets(rng)
    data, _ = _code(channels)
    with pytest.raises(CorruptStream):
        _code(channels, data[: len(data) // 3])
