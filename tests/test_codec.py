"""The bandelet transform end to end, and .bdl encode / decode (bandelets.transform.bandelets, .encoder,
.decoder)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import straight_edge

import bandelets
from bandelets import metrics
from bandelets.codec import encoder
from bandelets.codec.options import EncodeOptions
from bandelets.format.fields import WAVELETS, padded_shape
from bandelets.format.header import unpack
from bandelets.format.samples import as_read, from_samples, to_samples
from bandelets.search.lagrangian import LAMBDA
from bandelets.transform.wavelets import subband_slices


def _n_bandelet_squares(b) -> int:
    return sum(int(np.sum(tree.leaves()[3] >= 0)) for tree in b.trees)


def _image(shape, seed=0):
    """Straight edge + smooth ramp + a little noise: bandelets find directions in it."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]] / max(shape)
    return straight_edge(shape=shape) + 0.4 * x - 0.2 * y**2 + 0.01 * rng.standard_normal(shape)


# ---------------------------------------------------------------------------------------------
# The transform.


@pytest.mark.parametrize("wavelet", ["cdf97", "db4"])
@pytest.mark.parametrize("transform", ["bandelet", "wavelet"])
@pytest.mark.parametrize("shape", [(64, 64), (37, 53)])
def test_inverse_of_forward_is_exact(wavelet, transform, shape):
    x = _image(shape)
    b = bandelets.forward(x, 0.05, wavelet=wavelet, transform=transform)
    assert b.shape == shape
    assert b.coefficients.shape == padded_shape(shape, b.levels)
    if transform == "bandelet":
        assert _n_bandelet_squares(b) > 0  # otherwise this would only test wavelets
    else:
        assert _n_bandelet_squares(b) == 0
    np.testing.assert_allclose(bandelets.inverse(b), x, rtol=0, atol=1e-9)


@pytest.mark.filterwarnings("ignore:Level value:UserWarning")  # PyWavelets, long filters
@pytest.mark.parametrize("wavelet", WAVELETS)
def test_every_wavelet_round_trips(wavelet):
    x = _image((64, 48), seed=13)
    b = bandelets.forward(x, 0.05, wavelet=wavelet)
    np.testing.assert_allclose(bandelets.inverse(b), x, rtol=0, atol=1e-9)
    y = bandelets.decode(bandelets.encode(x, threshold=0.02, wavelet=wavelet))
    assert _rmse(x, y) < 0.02


@pytest.mark.parametrize("transform_1d", ["haar", "alpert2"])
def test_inverse_of_forward_for_each_1d_transform(transform_1d, edge_image):
    x = edge_image
    b = bandelets.forward(x, 0.05, transform_1d=transform_1d)
    assert b.transform_1d == transform_1d
    assert _n_bandelet_squares(b) > 0
    np.testing.assert_allclose(bandelets.inverse(b), x, rtol=0, atol=1e-9)


@pytest.mark.parametrize("shape", [(64, 64), (32, 96)])
def test_orthogonal_wavelet_bandelet_transform_preserves_energy(shape):
    # Sizes are multiples of 2**levels: no padding, which would add energy.
    x = _image(shape, seed=2)
    b = bandelets.forward(x, 0.05, wavelet="db4")
    assert b.coefficients.shape == shape
    assert _n_bandelet_squares(b) > 0
    assert np.sum(b.coefficients**2) == pytest.approx(np.sum(x**2), rel=1e-10)


def test_forward_keeps_wavelet_coefficients_outside_bandelet_squares():
    x = _image((64, 64), seed=3)
    b = bandelets.forward(x, 0.05)
    w = bandelets.forward(x, 0.05, transform="wavelet")
    differs = b.coefficients != w.coefficients
    assert differs.any()
    # Only inside the squares that have a direction.
    inside = np.zeros(x.shape, bool)
    for (_, _, (rows, cols)), tree in zip(subband_slices(x.shape, b.levels), b.trees, strict=True):
        for r, c, width, d in zip(*tree.leaves(), strict=True):
            if d >= 0:
                r0, c0 = rows.start + r, cols.start + c
                inside[r0 : r0 + width, c0 : c0 + width] = True
    assert not np.any(differs & ~inside)


def test_forward_rejects_bad_options():
    x = np.zeros((16, 16))
    for kwargs in [dict(transform="curvelet"), dict(wavelet="sym5"), dict(transform_1d="alpert3")]:
        with pytest.raises(ValueError, match="unknown"):
            bandelets.forward(x, 0.1, **kwargs)
    with pytest.raises(ValueError, match="threshold"):
        bandelets.forward(x, -1.0)


# ---------------------------------------------------------------------------------------------
# encode / decode.


def _rmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


@pytest.mark.parametrize(
    ("shape", "kwargs"),
    [
        ((48, 64), {}),
        ((40, 40, 3), {}),
        ((32, 48, 4), {}),
        ((48, 64), dict(transform="wavelet")),
        ((48, 64), dict(wavelet="db4")),
        ((48, 64), dict(transform_1d="haar")),
        ((32, 32, 3), dict(kind="geometry-image")),
    ],
)
def test_encode_decode_round_trip(shape, kwargs):
    t = 0.02
    base = _image(shape[:2], seed=4)
    x = base if len(shape) == 2 else np.stack([base * (k + 1) / 2 + k for k in range(shape[2])], -1)
    data = bandelets.encode(x, threshold=t, **kwargs)
    assert isinstance(data, bytes)
    header, _ = unpack(data)
    channels = 1 if len(shape) == 2 else shape[2]
    assert (header.height, header.width, header.channels) == (shape[0], shape[1], channels)
    assert header.threshold == float(np.float32(t))  # a float32 on disk
    y = bandelets.decode(data)
    assert y.shape == x.shape
    assert y.dtype == np.float64
    # Every coefficient is off by at most T (dead zone), about T / 2 above it.
    assert _rmse(x, y) < t
    # Deterministic.
    assert bandelets.encode(x, threshold=t, **kwargs) == data


def test_odd_size_round_trip():
    x = _image((200, 137), seed=5)
    data = bandelets.encode(x, threshold=0.05)
    y = bandelets.decode(data)
    assert y.shape == (200, 137)
    assert _rmse(x, y) < 0.05


@pytest.mark.parametrize("shape", [(8, 8), (2, 1), (1, 5), (3, 2, 3)])
def test_tiny_images(shape):
    x = np.random.default_rng(6).random(shape)
    y = bandelets.decode(bandelets.encode(x, threshold=0.01))
    assert y.shape == x.shape
    assert _rmse(x, y) < 0.02


@pytest.mark.parametrize("value", [0.0, 0.7, -250.0])
def test_constant_image(value):
    x = np.full((24, 40), value)
    data = bandelets.encode(x, threshold=0.01)
    y = bandelets.decode(data)
    assert y.shape == x.shape
    assert np.max(np.abs(y - value)) < 0.01
    # No detail to code: smaller than the same image with a little texture.
    texture = 0.05 * np.random.default_rng(12).standard_normal(x.shape)
    assert len(data) < len(bandelets.encode(x + texture, threshold=0.01))
    if value == 0.0:
        assert len(data) < 100


def test_integer_input_is_accepted():
    x = (np.random.default_rng(7).random((32, 32)) * 255).astype(np.uint8)
    y = bandelets.decode(bandelets.encode(x, threshold=1.0))
    assert _rmse(x.astype(float), y) < 1.0


def test_coefficient_sse_is_the_decoded_squared_error():
    """With an orthogonal wavelet and no padding the decoded error equals the quantization
    error of the coefficients (before the restoration and the loop filter, which only the decoded
    image sees)."""
    x = _image((64, 64), seed=8)
    t = 0.03
    options = EncodeOptions(wavelet="db4", restore=False, loop_filter=False)
    enc = encoder.encode_with_stats(x, options, threshold=t)
    assert enc.threshold == float(np.float32(t))
    y = bandelets.decode(enc.data)
    sse = float(np.sum((x - y) ** 2))
    assert sse > 0
    assert sse == pytest.approx(enc.coefficient_sse, rel=1e-6)


def test_normal_map_decodes_unit_vectors(crease_map):
    # Not unit length on input: encode renormalises first.
    x = crease_map * np.linspace(0.5, 2.0, 64)[:, None, None]
    data = bandelets.encode(x, threshold=0.02, kind="normal-map")
    assert unpack(data)[0].kind == "normal-map"
    y = bandelets.decode(data)
    assert y.shape == x.shape
    np.testing.assert_allclose(np.linalg.norm(y, axis=-1), 1.0, atol=1e-12)
    assert metrics.psnr(x, y, "normal-map") > 30


def test_normal_map_facing_up_is_coded_as_two_channels(crease_map):
    # Every z >= 0: only x and y are coded, z is rebuilt; the file is smaller than three
    # channels at the same threshold (the same map with one vector flipped below the plane),
    # even though those are coded in local frames, where z costs little.
    data = bandelets.encode(crease_map, threshold=0.01, kind="normal-map")
    assert unpack(data)[0].channels == 2
    y = bandelets.decode(data)
    assert y.shape == crease_map.shape
    assert np.all(y[..., 2] >= 0)
    assert metrics.psnr(crease_map, y, "normal-map") > 40
    flipped = crease_map.copy()
    flipped[0, 0, 2] = -flipped[0, 0, 2]
    three = bandelets.encode(flipped, threshold=0.01, kind="normal-map")
    assert unpack(three)[0].channels == 3
    assert len(data) < 0.9 * len(three)
    assert bandelets.decode(three)[0, 0, 2] < 0


def test_rebuilt_z_is_zero_outside_the_unit_disc():
    xy = np.array([[[0.6, 0.0], [0.9, 0.6]]])
    np.testing.assert_allclose(metrics.with_z(xy)[..., 2], [[0.8, 0.0]])


def test_auto_wavelet_keeps_the_better_file(crease_map):
    # The choice does not depend on the transform: wavelets keep the test fast.
    options = dict(kind="normal-map", transform="wavelet")
    # At a rate target: the file of the candidate whose decoded map has the higher PSNR.
    files = {w: bandelets.encode(crease_map, bpp=2, wavelet=w, **options) for w in encoder.AUTO_CANDIDATES}
    quality = {w: metrics.psnr(crease_map, bandelets.decode(d), "normal-map") for w, d in files.items()}
    best = max(quality, key=quality.get)
    auto = bandelets.encode(crease_map, bpp=2, wavelet="auto", **options)
    assert auto == files[best]
    assert unpack(auto)[0].wavelet == best
    # At a fixed threshold: the smaller error + LAMBDA T**2 bits.
    t = 0.02
    stats = [
        encoder.encode_with_stats(crease_map, EncodeOptions(wavelet=w, **options), threshold=t)
        for w in encoder.AUTO_CANDIDATES
    ]
    cost = [s.coefficient_sse + LAMBDA * t * t * 8 * len(s.data) for s in stats]
    chosen = stats[int(np.argmin(cost))].data
    assert bandelets.encode(crease_map, threshold=t, wavelet="auto", **options) == chosen
    # At a quality target: the smaller file.
    files = [bandelets.encode(crease_map, psnr=50, wavelet=w, **options) for w in encoder.AUTO_CANDIDATES]
    assert bandelets.encode(crease_map, psnr=50, wavelet="auto", **options) == min(files, key=len)


def test_normal_map_of_zero_vectors_decodes_to_plus_z():
    x = np.zeros((16, 16, 3))
    y = bandelets.decode(bandelets.encode(x, threshold=0.1, kind="normal-map"))
    np.testing.assert_allclose(y, np.broadcast_to([0.0, 0.0, 1.0], y.shape), atol=1e-6)


@pytest.fixture(scope="module")
def rate_image():
    return _image((128, 128), seed=9)


@pytest.mark.parametrize("bpp", [0.25, 1.0, 3.0])
def test_rate_control_meets_the_target_size(rate_image, bpp):
    data = bandelets.encode(rate_image, bpp=bpp)
    target = bpp * 128 * 128 / 8
    assert 0.97 * target <= len(data) <= target


def test_rate_control_for_wavelets_and_normal_maps(crease_map):
    data = bandelets.encode(crease_map, bpp=1.5, kind="normal-map", transform="wavelet")
    target = 1.5 * 64 * 64 / 8
    assert 0.97 * target <= len(data) <= target


@pytest.mark.parametrize(("kind", "target"), [("image", 32.0), ("image", 44.0), ("normal-map", 36.0)])
def test_psnr_target_is_met(kind, target, crease_map):
    x = _image((64, 64), seed=10) if kind == "image" else crease_map
    data = bandelets.encode(x, psnr=target, kind=kind)
    reached = metrics.psnr(x, bandelets.decode(data), kind)
    assert reached >= target
    # And not by a wide margin: rate control looks for the smallest such file.
    assert reached < target + 3


# ---------------------------------------------------------------------------------------------
# Errors.

GOOD = np.random.default_rng(11).random((32, 32))


@pytest.mark.parametrize(
    ("array", "kwargs", "words"),
    [
        (np.where(GOOD > 0.5, np.nan, GOOD), dict(bpp=1), "NaN"),
        (np.where(GOOD > 0.5, np.inf, GOOD), dict(bpp=1), "infinite"),
        (np.where(GOOD > 0.5, -np.inf, GOOD), dict(threshold=0.1), "infinite"),
        (np.zeros((0, 0)), dict(bpp=1), "too small"),
        (np.zeros((0, 5)), dict(bpp=1), "too small"),
        (np.zeros(0), dict(bpp=1), "shape"),
        (np.ones((1, 1)), dict(threshold=0.1), "too small"),
        (np.ones((2, 2, 2, 2, 2)), dict(bpp=1), "shape"),
        (np.ones((8, 8, 5)), dict(bpp=1), "channels"),
        (np.ones(16), dict(bpp=1), "shape"),
        (GOOD[..., None].repeat(4, -1), dict(bpp=1, kind="normal-map"), "3 channels"),
        (GOOD[..., None].repeat(2, -1), dict(bpp=1, kind="normal-map", xy=True), "3 channels"),
        (GOOD[..., None].repeat(3, -1), dict(bpp=1, xy=True), "normal maps only"),
        (np.ones((8, 8, 3), np.int32), dict(bpp=1, kind="normal-map"), "uint8 / uint16"),
        (np.ones((8, 8, 3), np.uint8), dict(bpp=1, kind="normal-map", depth=16), "depth 8"),
        (GOOD[..., None].repeat(4, -1), dict(bpp=1, kind="geometry-image"), "3 channels"),
        ("not an image", dict(bpp=1), "numeric"),
        (GOOD, dict(bpp=0), "bpp"),
        (GOOD, dict(bpp=-2), "bpp"),
        (GOOD, dict(bpp=float("nan")), "bpp"),
        (GOOD, dict(threshold=-0.5), "threshold"),
        (GOOD, dict(threshold=float("inf")), "threshold"),
        (GOOD, dict(psnr=float("nan")), "psnr"),
        (GOOD, dict(bpp=0.05), "cannot be reached"),  # 6 bytes
        (GOOD, dict(psnr=500.0), "cannot be reached"),
        (GOOD, dict(bpp=1, threshold=0.1), "exactly one"),
        (GOOD, dict(bpp=1, psnr=30), "exactly one"),
        (GOOD, dict(), "exactly one"),
        (GOOD, dict(bpp=1, transform="curvelet"), "unknown transform"),
        (GOOD, dict(bpp=1, wavelet="sym5"), "unknown wavelet"),
        (GOOD, dict(bpp=1, kind="depth-map"), "unknown kind"),
        (GOOD, dict(bpp=1, transform_1d="alpert3"), "unknown 1D transform"),
        (GOOD, dict(bpp=1, depth=12), "depth"),
    ],
)
def test_encode_errors_are_value_errors(array, kwargs, words):
    with pytest.raises(ValueError, match=words):
        bandelets.encode(array, **kwargs)


def test_bpp_below_one_byte_names_the_unreachable_target():
    with pytest.raises(ValueError, match="cannot be reached"):
        bandelets.encode(GOOD, bpp=0.0001)  # 32 x 32 x 0.0001 / 8 -> 0 bytes


def test_zero_threshold_is_a_value_error():
    with pytest.raises(ValueError, match="threshold"):
        bandelets.encode(GOOD, threshold=0)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_zero_threshold_without_basis_search_is_a_value_error():
    # Without the search, quantize() is what refuses it (by luck: 0 slips the option check).
    with pytest.raises(ValueError, match="threshold"):
        bandelets.encode(GOOD, threshold=0, transform="wavelet")


def test_files_are_identical_run_after_run_and_on_any_number_of_threads(crease_map):
    import numba

    files = []
    for threads in (1, numba.config.NUMBA_NUM_THREADS, 1):
        numba.set_num_threads(threads)
        try:
            files.append(bandelets.encode(crease_map, threshold=0.02, kind="normal-map"))
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    assert files[0] == files[1] == files[2]


def test_max_angle_target_holds_on_the_99th_percentile(crease_map):
    target = 4.0
    data = bandelets.encode(crease_map, max_angle=target, kind="normal-map")
    error = metrics.angular_error(crease_map, bandelets.decode(data))
    assert 0.8 * target < error.p99 <= target
    tighter = bandelets.encode(crease_map, max_angle=target / 2, kind="normal-map")
    assert len(tighter) > len(data)
    with pytest.raises(ValueError, match="normal maps only"):
        bandelets.encode(crease_map, max_angle=target)
    with pytest.raises(ValueError, match="from 0 to 180"):
        bandelets.encode(crease_map, max_angle=-1.0, kind="normal-map")


def test_psnr_target_holds_at_the_source_depth(crease_map):
    """The PSNR of what the user gets: the decoded map written as 8-bit samples."""
    source = as_read(crease_map, "normal-map", 8)  # an 8-bit PNG's values
    decoded = bandelets.decode(bandelets.encode(source, psnr=36.0, kind="normal-map", depth=8))
    assert metrics.psnr(source, as_read(decoded, "normal-map", 8), "normal-map") >= 36.0


def test_integer_normal_maps_are_samples(crease_map):
    """uint8 samples (an image's pixels) are mapped as PNG samples, and their depth recorded."""
    pixels = to_samples(crease_map, "normal-map", 8)
    data = bandelets.encode(pixels, threshold=0.02, kind="normal-map")
    assert unpack(data)[0].depth == 8
    same = bandelets.encode(from_samples(pixels, "normal-map", 8), threshold=0.02, kind="normal-map", depth=8)
    assert data == same
    assert metrics.angular_error(crease_map, bandelets.decode(data)).mean < 2


@pytest.mark.parametrize("layout", ["xy", "rg"])
def test_xy_normal_maps_decode_to_their_layout(crease_map, layout):
    xy = crease_map[..., :2]
    given = xy if layout == "xy" else np.concatenate([xy, np.full(xy.shape[:2] + (1,), 0.3)], axis=-1)
    data = bandelets.encode(given, threshold=0.02, kind="normal-map", xy=layout == "rg")
    header = unpack(data)[0]
    assert (header.channels, header.layout) == (2, layout)
    decoded = bandelets.decode(data)
    assert decoded.shape == given.shape
    assert metrics.angular_error(crease_map, decoded).mean < 1.5
    if layout == "rg":  # the unused blue is not coded: the decoder fills in the rebuilt z
        np.testing.assert_allclose(decoded, metrics.with_z(decoded[..., :2]), atol=1e-12)


def test_progress_line_names_every_stage(crease_map, capsys, monkeypatch):
    import functools

    from tqdm import tqdm

    from bandelets.runtime import progress

    # tqdm redraws at most every 0.1 s: here at every step, so what shows does not hang on timing.
    monkeypatch.setattr(progress, "tqdm", functools.partial(tqdm, mininterval=0, miniters=1))
    bandelets.encode(crease_map, psnr=40, kind="normal-map", progress=True)
    err = capsys.readouterr().err
    assert "rate control: " in err and "restoration search: " in err and "T=" in err
    # Counted across the restoration searches (two or more tries here): not reset by each.
    assert max(int(n) for n in re.findall(r"rate control: (\d+)", err)) >= 2
    bandelets.encode(crease_map, psnr=40, kind="normal-map")
    assert capsys.readouterr().err == ""


def test_xy_beyond_the_rim_are_coded_as_given(crease_map):
    """x, y beyond the unit disc (z rebuilt as 0, as 8-bit maps have) are not pulled onto the rim,
    where they would decode just inside it, tilted by the steep z."""
    xy = crease_map[..., :2].copy()
    xy[:8] = [0.8, 0.7]  # |x, y| = 1.06
    decoded = bandelets.decode(bandelets.encode(xy, threshold=2e-4, kind="normal-map", restore=False))
    assert metrics.angular_error(xy[:8], decoded[:8]).max < 0.1


def test_maps_facing_one_way_are_coded_as_two_channels():
    from bandelets.transform.normals import ONE_WAY

    for angle, channels in ((0.9 * ONE_WAY, 2), (1.1 * ONE_WAY, 3)):
        tilt = np.broadcast_to(np.linspace(0.0, angle, 32), (32, 32))  # turning about y, left to right
        normals = np.stack([np.sin(tilt), np.zeros_like(tilt), np.cos(tilt)], axis=-1)
        assert unpack(bandelets.encode(normals, bpp=2.0, kind="normal-map"))[0].channels == channels
