"""The loop filter: its section read back bit-exactly, hostile sections refused, and the encoder's
choice never worse than no filter at the price of its bytes."""

from __future__ import annotations

import struct
import zlib
from dataclasses import replace

import numpy as np
import pytest

import bandelets
from bandelets.codec.decoder import decode_parsed
from bandelets.codec.encoder import encode_with_stats
from bandelets.codec.options import EncodeOptions
from bandelets.format.fields import MAX_FILTER_CLIP, MAX_FILTER_SHIFT, MAX_FILTER_WIDTH, FormatError
from bandelets.format.filter import LoopFilter, filter_cross_offsets, filter_offsets, filter_taps
from bandelets.format.header import Header, pack, unpack
from bandelets.metrics import psnr
from bandelets.restore import loopfilter
from bandelets.samples import bump_normal_map, crease_normal_map
from bandelets.search.lagrangian import LAMBDA


def _header(channels: int = 2, loop_filter: LoopFilter | None = None) -> Header:
    return Header(
        height=8,
        width=8,
        channels=channels,
        kind="normal-map" if channels == 2 else "image",
        transform="bandelet",
        wavelet="cdf97",
        levels=1,
        threshold=0.5,
        loop_filter=loop_filter,
    )


@pytest.mark.parametrize(
    ("radius", "cross", "square", "channels"),
    [
        (1, 0, False, 1),
        (2, 0, True, 2),
        (3, 1, False, 2),
        (3, 1, False, 3),
        (3, 2, False, 2),
        (3, 2, True, 3),
    ],
)
def test_a_filter_is_read_back_bit_exactly(radius, cross, square, channels):
    rng = np.random.default_rng(radius + channels)
    count = channels * filter_taps(radius, cross, channels, square)
    for largest in (1, 100, 2**MAX_FILTER_WIDTH // 2 - 1):
        coefficients = tuple(int(v) for v in rng.integers(-largest, largest + 1, count))
        f = LoopFilter(
            radius=radius, cross=cross, square=square, clip=largest % 7, shift=11, coefficients=coefficients
        )
        header = _header(channels, f)
        data = pack(header, (b"", b"", b"ab"))
        got, streams = unpack(data)
        assert (replace(got, segments=()), streams) == (header, (b"", b"", b"ab"))  # segments: format 19


def test_filter_shapes_count_their_taps():
    # A diamond of radius 3 (12 pairs of taps), the 3 x 3 / 5 x 5 square of each other channel (4 / 12).
    assert [filter_taps(3, cross, 3) for cross in (0, 1, 2)] == [12, 12 + 2 * 4, 12 + 2 * 12]
    assert filter_taps(2, 2, 1) == 6
    assert [filter_taps(radius, 0, 1, square=True) for radius in (1, 2, 3)] == [4, 12, 24]


def test_a_large_image_is_filtered_in_bands_of_rows_as_in_one(monkeypatch):
    """Above ``THREADED_PIXELS`` the rows are filtered in bands, in threads: the same numbers."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(2, 300, 260))
    f = LoopFilter(
        radius=3, cross=2, square=True, clip=2, shift=6, coefficients=tuple(rng.integers(-40, 40, 2 * 36))
    )
    monkeypatch.setattr(loopfilter, "CORES", 3)
    banded = loopfilter.apply(x, f, 0.5, 300, 260)
    monkeypatch.setattr(loopfilter, "THREADED_PIXELS", 10**9)
    np.testing.assert_array_equal(banded, loopfilter.apply(x, f, 0.5, 300, 260))


def _folded_pad(x: np.ndarray, k: int) -> np.ndarray:
    """``x`` (C, H, W) extended by ``k`` pixels past each edge as an octahedral geometry image is glued:
    row ``-1 - a`` is row ``a`` reversed, column ``-1 - b`` is column ``b`` upside down (corners too)."""
    rows = np.concatenate([x[:, k - 1 :: -1, ::-1], x, x[:, : -k - 1 : -1, ::-1]], axis=1)
    return np.concatenate([rows[:, ::-1, k - 1 :: -1], rows, rows[:, ::-1, : -k - 1 : -1]], axis=2)


@pytest.mark.parametrize(
    ("radius", "cross", "square", "clip", "folded"),
    [(2, 0, False, 0, False), (3, 1, False, 3, False), (3, 2, True, 2, False), (3, 2, True, 2, True)],
)
def test_the_filter_is_the_clipped_second_differences_of_its_offsets(radius, cross, square, clip, folded):
    """``apply`` against numpy: each channel plus the weighted clipped second differences of its own
    diamond or square and of the other channel's square, the border replicated, or ``folded``: the
    samples past it those across the folds of an octahedral geometry image."""
    rng = np.random.default_rng(radius + cross)
    side = 21 if folded else 19
    x = rng.normal(size=(2, side, 23))
    n = filter_taps(radius, cross, 2, square)
    f = LoopFilter(
        radius=radius,
        cross=cross,
        square=square,
        clip=clip,
        shift=6,
        coefficients=tuple(rng.integers(-40, 40, 2 * n)),
    )
    if folded:
        x = x[:, :, :side]
    out = loopfilter.apply(x, f, 0.5, *x.shape[1:], folded=folded)
    bound = loopfilter.clip_bound(clip, 0.5)
    padded = _folded_pad(x, 3) if folded else np.pad(x, ((0, 0), (3, 3), (3, 3)), mode="edge")
    for c in range(2):
        taps = [(c, o) for o in filter_offsets(radius, square)] + [
            (1 - c, o) for o in filter_cross_offsets(cross)
        ]
        expected = x[c].copy()
        for (k, (dy, dx)), w in zip(taps, f.coefficients[c * n : (c + 1) * n], strict=True):
            plus = padded[k, 3 + dy : 3 + dy + side, 3 + dx : 3 + dx + x.shape[2]] - x[k]
            minus = padded[k, 3 - dy : 3 - dy + side, 3 - dx : 3 - dx + x.shape[2]] - x[k]
            expected += w / 64 * (np.clip(plus, -bound, bound) + np.clip(minus, -bound, bound))
        np.testing.assert_allclose(out[c], expected, atol=1e-12)


def test_the_encoders_filter_is_what_the_decoder_applies():
    x = bump_normal_map(96)
    encoded = encode_with_stats(x, EncodeOptions(kind="normal-map"), bpp=1.0, measured=True)
    header, _ = unpack(encoded.data)
    assert header.loop_filter is not None
    decoded = bandelets.decode(encoded.data)
    np.testing.assert_array_equal(decoded, encoded.decoded)
    assert psnr(x, decoded, "normal-map") == pytest.approx(encoded.psnr, abs=1e-6)
    # Without the restoration (a preview), the filter is not applied either.
    preview = bandelets.decode(encoded.data, restore=False)
    unfiltered = unpack(pack(replace(header, restoration=0, loop_filter=None), unpack(encoded.data)[1]))
    np.testing.assert_array_equal(preview, decode_parsed(*unfiltered))


def _section(data: bytes, section: bytes) -> bytes:
    """``data`` (a file without a filter) with ``section`` after its streams, the flag of a loop
    filter set (byte 8), a valid CRC."""
    body = bytearray(data[:-4] + section)
    body[8] |= 128
    return bytes(body) + struct.pack("<I", zlib.crc32(body))


@pytest.fixture(scope="module")
def plain_file():
    x = crease_normal_map(32)
    return bandelets.encode(x, threshold=0.05, kind="normal-map", loop_filter=False)


@pytest.mark.parametrize(
    ("section", "words"),
    [
        (b"", "stream lengths"),  # the flag without a section
        (b"\x03", "section of 1 bytes"),
        (bytes([3 + 12, 8, 8, 0]) + bytes(100), "shape"),  # a cross-channel square of radius 3
        (bytes([3 + 32, 8, 8, 0]) + bytes(100), "shape"),  # a flag that does not exist
        (bytes([0, 8, 8, 0]) + bytes(100), "shape"),  # radius 0
        (bytes([3, MAX_FILTER_SHIFT + 1, 8, 0]) + bytes(24), "shift"),
        (bytes([3, 8, 1, 0]) + bytes(6), "bits"),
        (bytes([3, 8, MAX_FILTER_WIDTH + 1, 0]) + bytes(100), "bits"),
        (bytes([3, 8, 8, MAX_FILTER_CLIP + 1]) + bytes(24), "clipping"),
        (bytes([3, 8, 8, 0]) + bytes(25), "24 coefficients of 8 bits in 29 bytes"),
        (bytes([3, 8, 8, 0]) + bytes(2**20), "stream lengths"),  # a huge section
    ],
    ids=["none", "short", "cross", "flag", "radius", "shift", "narrow", "wide", "clip", "length", "huge"],
)
def test_hostile_filter_sections_are_format_errors(plain_file, section, words):
    assert unpack(plain_file)[0].loop_filter is None
    with pytest.raises(FormatError, match=words):
        bandelets.decode(_section(plain_file, section))


def test_cross_channel_taps_need_two_or_three_channels():
    image = np.random.default_rng(1).random((16, 16))
    data = bandelets.encode(image, threshold=0.1, loop_filter=False)
    with pytest.raises(FormatError, match="cross-channel"):
        bandelets.decode(_section(data, bytes([3 + 4, 8, 8, 0]) + bytes(16)))
    with pytest.raises(ValueError, match="not a loop filter"):
        pack(
            _header(1, LoopFilter(radius=1, cross=1, clip=0, shift=8, coefficients=(0, 0))),
            (b"", b"", b""),
        )


@pytest.mark.parametrize(
    "make",
    [
        lambda: crease_normal_map(64),
        lambda: bump_normal_map(64),
        lambda: np.random.default_rng(3).random((48, 40)),  # noise: nothing to learn
        lambda: np.linspace(0, 1, 48 * 40).reshape(48, 40),
    ],
)
@pytest.mark.parametrize("threshold", [0.02, 0.2])
def test_a_filter_is_written_only_where_it_pays_for_its_bytes(make, threshold):
    x = make()
    kind = "normal-map" if x.ndim == 3 else "image"
    without = bandelets.encode(x, threshold=threshold, kind=kind, loop_filter=False)
    with_filter = bandelets.encode(x, threshold=threshold, kind=kind)
    header, streams = unpack(with_filter)
    assert unpack(without) == (replace(header, loop_filter=None), streams)  # same streams
    extra = 8 * (len(with_filter) - len(without))
    if header.loop_filter is None:
        assert extra == 0
        return
    # The squared error (as the PSNR counts it) falls by more than the price of the bytes.
    p, q = (psnr(x, bandelets.decode(d), kind) for d in (without, with_filter))
    samples = x.size if kind == "image" else x.shape[0] * x.shape[1] * 3
    top = np.ptp(x) if kind == "image" else 1.0
    error = [samples * top**2 * 10 ** (-v / 10) for v in (p, q)]
    assert error[0] - error[1] > LAMBDA * threshold**2 * extra * (1 - 1e-9)
    assert q > p


def test_a_rate_target_counts_the_filters_bytes():
    x = bump_normal_map(96)
    filtered = 0
    for bpp in (0.5, 1.0, 2.0):
        data = bandelets.encode(x, bpp=bpp, kind="normal-map")
        filtered += unpack(data)[0].loop_filter is not None
        assert 8 * len(data) <= bpp * 96 * 96
    assert filtered >= 2


def test_a_flat_image_gets_no_filter():
    data = bandelets.encode(np.full((16, 16), 0.5), threshold=0.01)
    assert unpack(data)[0].loop_filter is None
    assert loopfilter.reserve(2) > 0
