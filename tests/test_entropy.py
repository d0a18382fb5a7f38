"""The adaptive binary range coder (bandelets.coding.rangecoder)."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.coding import coefficients, rangecoder
from bandelets.coding.rangecoder import Coder, CorruptStream, code_flag_map, code_flags, code_symbols


def _encode_flags(bits, ctxs, n_contexts):
    coder = Coder(n_contexts)
    code_flags(coder, bits, ctxs)
    return coder.finish()


def _decode_flags(data, ctxs, n_contexts):
    coder = Coder(n_contexts, data)
    out = code_flags(coder, np.zeros(len(ctxs), np.int64), ctxs)
    return out, coder


@pytest.mark.parametrize("n", [0, 1, 7, 5000])
def test_flags_round_trip(n, rng):
    n_contexts = 6
    ctxs = rng.integers(0, n_contexts, n)
    # Each context has its own bias, so the contexts matter.
    p = np.linspace(0.05, 0.95, n_contexts)[ctxs]
    bits = (rng.random(n) < p).astype(np.int64)
    data = _encode_flags(bits, ctxs, n_contexts)
    assert isinstance(data, bytes)
    decoded, coder = _decode_flags(data, ctxs, n_contexts)
    coder.check()
    np.testing.assert_array_equal(decoded, bits)


def test_flags_with_wrong_contexts_do_not_decode(rng):
    n = 3000
    ctxs = rng.integers(0, 4, n)
    bits = (rng.random(n) < np.array([0.05, 0.95, 0.2, 0.8])[ctxs]).astype(np.int64)
    data = _encode_flags(bits, ctxs, 4)
    # (A permutation of the context labels would decode fine: merge two contexts instead.)
    decoded, _ = _decode_flags(data, np.where(ctxs == 1, 0, ctxs), 4)
    assert not np.array_equal(decoded, bits)


@pytest.mark.parametrize("shape", [(0, 5), (1, 1), (3, 7), (40, 40)])
def test_flag_map_round_trips_and_its_neighbours_pay(shape, rng):
    # Lines of ones, as a crease moves a line of blocks: the neighbour counts predict them.
    bits = np.zeros(shape, np.int64)
    for _ in range(shape[0] // 8):
        r, c = rng.integers(0, shape[0]), rng.integers(0, max(shape[1] - 12, 1))
        bits[r, c : c + 12] = 1
        bits[r:, c] = 1
    bits |= (rng.random(shape) < 0.02).astype(np.int64)
    ctxs = np.zeros(shape, np.int64)
    coder = Coder(3)
    code_flag_map(coder, bits, ctxs, 1)
    data = coder.finish()
    decoder = Coder(3, data)
    np.testing.assert_array_equal(code_flag_map(decoder, np.zeros(shape, np.int64), ctxs, 1), bits)
    decoder.check()
    if bits.size > 1000:  # the same flags without the neighbours cost more
        assert len(data) < 0.8 * len(_encode_flags(bits.ravel(), ctxs.ravel(), 1))


def test_several_calls_share_one_stream(rng):
    parts = [(rng.random(n) < 0.3).astype(np.int64) for n in (10, 0, 300, 1)]
    coder = Coder(2)
    for i, bits in enumerate(parts):
        code_flags(coder, bits, np.full(bits.shape, i % 2))
    data = coder.finish()
    decoder = Coder(2, data)
    for i, bits in enumerate(parts):
        got = code_flags(decoder, np.zeros_like(bits), np.full(bits.shape, i % 2))
        np.testing.assert_array_equal(got, bits)
    decoder.check()


def test_symbols_round_trip(rng):
    n = 4000
    n_bits = rng.integers(1, 8, n)
    symbols = (rng.random(n) ** 3 * (1 << n_bits)).astype(np.int64)  # skewed to small values
    bases = np.where(n_bits > 4, 0, 300)  # two separate models
    coder = Coder(600)
    code_symbols(coder, symbols, bases, n_bits)
    data = coder.finish()
    decoder = Coder(600, data)
    got = code_symbols(decoder, np.zeros(n, np.int64), bases, n_bits)
    decoder.check()
    np.testing.assert_array_equal(got, symbols)


@pytest.mark.skipif(not hasattr(rangecoder, "code_positive"), reason="no code_positive here")
def test_positive_integers_round_trip(rng):
    values = rng.geometric(0.2, 3000).astype(np.int64)
    values[:3] = [1, 2, 1 << 20]
    bases = np.zeros(values.shape, np.int64)
    coder = Coder(64)
    rangecoder.code_positive(coder, values, bases)
    data = coder.finish()
    decoder = Coder(64, data)
    got = rangecoder.code_positive(decoder, np.ones(values.shape, np.int64), bases)
    decoder.check()
    np.testing.assert_array_equal(got, values)


@pytest.mark.parametrize("p", [0.05, 0.1, 0.3])
def test_skewed_source_compresses_to_its_entropy(p, rng):
    n = 60000
    bits = (rng.random(n) < p).astype(np.int64)
    data = _encode_flags(bits, np.zeros(n, np.int64), 1)
    q = bits.mean()
    entropy_bits = n * -(q * np.log2(q) + (1 - q) * np.log2(1 - q))
    assert 8 * len(data) <= 1.03 * entropy_bits
    # A coder cannot beat the entropy by more than its flush bytes allow.
    assert 8 * len(data) >= 0.97 * entropy_bits


def test_equiprobable_bits_cost_one_bit_each(rng):
    n = 40000
    bits = rng.integers(0, 2, n)
    data = _encode_flags(bits, np.zeros(n, np.int64), 1)
    assert 8 * len(data) == pytest.approx(n, rel=0.03)


def test_truncated_flag_stream_raises_corrupt_stream_or_returns(rng):
    n = 4000
    ctxs = rng.integers(0, 3, n)
    bits = (rng.random(n) < 0.3).astype(np.int64)
    data = _encode_flags(bits, ctxs, 3)
    assert len(data) > 100
    raised = 0
    for cut in [0, 1, 2, 3, 4, 5, 8, len(data) // 3, len(data) // 2, len(data) - 9, len(data) - 6]:
        decoded, coder = _decode_flags(data[:cut], ctxs, 3)
        assert decoded.shape == bits.shape
        assert set(np.unique(decoded)) <= {0, 1}
        try:
            coder.check()
        except CorruptStream as err:
            assert isinstance(err, ValueError)
            raised += 1
    # Deep truncations are detected.
    assert raised >= 5


def test_check_passes_on_a_complete_stream_and_encoder():
    coder = Coder(1)
    code_flags(coder, np.ones(100, np.int64), np.zeros(100, np.int64))
    coder.check()  # an encoder never overruns
    data = coder.finish()
    decoder = Coder(1, data)
    code_flags(decoder, np.zeros(100, np.int64), np.zeros(100, np.int64))
    decoder.check()


def test_encoder_buffer_grows(rng):
    n = 200000  # far more than the initial 64 kB capacity at 1 bit per flag
    bits = rng.integers(0, 2, n)
    coder = Coder(1, capacity=16)
    code_flags(coder, bits, np.zeros(n, np.int64))
    data = coder.finish()
    got, _ = _decode_flags(data, np.zeros(n, np.int64), 1)
    np.testing.assert_array_equal(got, bits)


def test_rarely_used_contexts_learn_from_their_family():
    # 15 wavelet classes, each coding 6 zeros (no neighbours, no guide): each class's own
    # significance context sees 6 decisions, their common coarse context all 90.
    from bandelets.coding.order import Segment

    n = 90
    plan = Segment(np.arange(n), 1 + np.arange(n) % 15, np.full((n, 6), -1))
    q = np.zeros(n, np.int32)
    spent = np.zeros(n)
    coder = Coder(coefficients.coefficient_contexts())
    coefficients.code_coefficients(coder, q, plan, np.zeros(n, np.int64), np.zeros(0, np.int32), spent)
    # The same decisions, each class learning alone from 1/2.
    alone = Coder(16)
    code_flags(alone, np.zeros(n, np.int64), plan.classes)
    unbacked = alone.state[rangecoder.SPENT] / rangecoder.COST_SCALE
    assert spent.sum() < 0.6 * unbacked
    decoder = Coder(coefficients.coefficient_contexts(), coder.finish())
    out = np.ones(n, np.int32)
    coefficients.code_coefficients(
        decoder, out, plan, np.zeros(n, np.int64), np.zeros(0, np.int32), np.zeros(n)
    )
    np.testing.assert_array_equal(out, q)


def test_coefficients_round_trip_and_the_encoder_prices_each_one(rng):
    # Every path of the coefficient coder: zeros, +-1, +-2, large magnitudes (Elias-gamma), the
    # approximation's prediction, neighbours, parents and a guide channel.
    from bandelets.coding.order import approximation_plan, subband_plan
    from bandelets.transform.quadtree import flat_quadtree

    shape, levels = (32, 32), 2
    size = shape[0] * shape[1]
    plans = [approximation_plan(shape, levels)]
    for index in range(3 * levels):
        band = ((shape[0] >> levels) << (index // 3),) * 2
        plans += subband_plan(shape, levels, index, flat_quadtree(band, 0), "haar")
    guide = rng.integers(-3, 4, size).astype(np.int32)
    q = np.where(rng.random(size) < 0.6, 0, rng.integers(-40, 41, size)).astype(np.int32)
    q[plans[0].order] = rng.integers(-2000, 2000, plans[0].order.size)
    encoder, known, spent = (
        Coder(coefficients.coefficient_contexts()),
        np.zeros(size, np.int64),
        np.zeros(size),
    )
    for plan in plans:
        coefficients.code_coefficients(encoder, q, plan, known, guide, spent)
    assert sum(p.order.size for p in plans) == size
    assert np.all(spent > 0)
    # The per-coefficient prices add up to the coder's own ledger.
    assert spent.sum() == pytest.approx(encoder.state[rangecoder.SPENT] / rangecoder.COST_SCALE)
    data = encoder.finish()
    assert 8 * len(data) == pytest.approx(spent.sum(), rel=0.02, abs=64)
    decoder, out = Coder(coefficients.coefficient_contexts(), data), np.zeros(size, np.int32)
    known = np.zeros(size, np.int64)
    for plan in plans:
        coefficients.code_coefficients(decoder, out, plan, known, guide, np.zeros(size))
    np.testing.assert_array_equal(out, q)
    decoder.check()
    # Cut short, the same stream is refused (the decoder counts the bytes it reads past the end).
    decoder, known = (
        Coder(coefficients.coefficient_contexts(), data[: len(data) // 2]),
        np.zeros(size, np.int64),
    )
    with pytest.raises(CorruptStream):
        for plan in plans:
            coefficients.code_coefficients(
                decoder, np.zeros(size, np.int32), plan, known, guide, np.zeros(size)
            )
