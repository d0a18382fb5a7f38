"""Decoder-side restoration (bandelets.restoration) and its place in the codec."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import bandelets
from bandelets import codec, metrics, restoration
from bandelets.bitstream import pack, unpack
from bandelets.quantize import dequantize, quantize
from bandelets.wavelets import wavedec, waverec


def test_bins_hold_the_values_they_came_from(rng):
    t = 0.1
    x = rng.normal(scale=0.5, size=1000)
    q = quantize(x, t)
    # What the encoder's rate-distortion optimised quantization may also do.
    moved = q.copy()
    moved[(np.abs(q) == 1) & (rng.random(q.shape) < 0.5)] = 0
    promote = (q == 0) & (np.abs(x) > 0.7 * t)
    moved[promote] = np.sign(x[promote]).astype(moved.dtype)
    for bins in (q, moved):
        low, high = restoration.bin_bounds(bins, t)
        assert np.all((low <= x) & (x <= high))
        assert np.all(high - low <= 4 * t)
        # The plain reconstruction lies in its own bin.
        r = dequantize(bins, t)
        assert np.all((low <= r) & (r <= high))


def _penalty(x, smoothing, edge):
    dx = np.diff(x, axis=2, append=x[:, :, -1:])
    dy = np.diff(x, axis=1, append=x[:, -1:, :])
    n = np.sqrt(np.sum(dx**2 + dy**2, axis=0) + smoothing**2)
    return np.sum(edge * np.log1p(n / edge))


@pytest.mark.parametrize("edge", [0.05, 1e6])  # a log total variation; the total variation
def test_penalty_gradient_is_the_derivative(rng, edge):
    x = rng.random((2, 5, 7))
    gradient = restoration.penalty_gradient(x, 0.1, edge)
    h = 1e-6
    numeric = np.zeros_like(x)
    for index in np.ndindex(x.shape):
        step = np.zeros_like(x)
        step[index] = h
        numeric[index] = (_penalty(x + step, 0.1, edge) - _penalty(x - step, 0.1, edge)) / (2 * h)
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-7)


def test_the_penalty_keeps_a_crease_and_flattens_ripples():
    """Where the gradient is far above ``edge`` the pull is far weaker than on a small ripple."""
    x = np.zeros((1, 4, 8))
    x[0, :, 4:] = 1.0  # a crease between columns 3 and 4
    x[0, :, 1] += 0.01  # a ripple
    g = restoration.penalty_gradient(x, 1e-4, 0.05)
    assert abs(g[0, 1, 3]) < 0.1 * abs(g[0, 1, 1])


def test_iterations_stay_consistent_with_the_bins(edge_image):
    """Each step keeps every coefficient of an orthogonal transform inside its bin, and the first
    estimate is the plain dequantized image."""
    t = 0.05

    def analysis(x):
        return wavedec(x, "db4", 3)

    def synthesis(c):
        return waverec(c, "db4", 3)

    q = quantize(analysis(edge_image), t)
    low, high = restoration.bin_bounds(q, t)
    steps = restoration.iterate([q], t, analysis, synthesis)
    first = next(steps)[0].copy()
    np.testing.assert_allclose(first, synthesis(dequantize(q, t)))
    for _ in range(5):
        x = next(steps)[0]
    c = analysis(x)
    assert np.all((c >= low - 1e-9) & (c <= high + 1e-9))
    assert not np.allclose(x, first)
    # Smoother than where it started: the penalty went down.
    t_edge = restoration.EDGE * t
    assert _penalty(x[None], 1e-9, t_edge) < _penalty(first[None], 1e-9, t_edge)


def test_restoration_improves_a_crease_map_at_no_cost(crease_map):
    plain = bandelets.encode(crease_map, bpp=1.0, kind="normal-map", restore=False)
    data = bandelets.encode(crease_map, bpp=1.0, kind="normal-map")
    header, streams = unpack(data)
    assert header.restoration > 0
    # Same streams, same size: only the header's count differs.
    assert (len(data), streams) == (len(plain), unpack(plain)[1])
    gain = metrics.psnr(crease_map, bandelets.decode(data), "normal-map") - metrics.psnr(
        crease_map, bandelets.decode(plain), "normal-map"
    )
    assert gain > 0.3


def test_three_channel_normal_maps_are_restored_on_the_sphere(crease_map):
    """With z coded (some normals face away), each step brings the vectors back to unit length,
    which restores better than the same steps off the sphere."""
    normals = crease_map.copy()
    normals[:, :32, 2] *= -1  # half of them face away: three channels coded
    data = bandelets.encode(normals, bpp=1.0, kind="normal-map", restore=False)
    header, streams = unpack(data)
    assert header.channels == 3
    trees, quantized = codec._decoded_bins(header, streams)
    transforms = codec._transforms(header, trees)

    def best(unit_vectors):
        steps = restoration.iterate(quantized, header.threshold, *transforms, unit_vectors=unit_vectors)
        return max(metrics.psnr(normals, codec._output(next(steps), header), "normal-map") for _ in range(30))

    assert best((64, 64)) > best(None) + 0.05


@pytest.mark.parametrize("kind", ["image", "normal-map"])
def test_the_encoder_never_picks_a_worse_restoration(rng, kind):
    """On noise, restoring may not help: the count chosen never decodes worse than none."""
    x = rng.normal(size=(48, 40, 3))
    if kind == "normal-map":
        x = metrics.unit_vectors(x)
    reference = metrics.unit_vectors(x) if kind == "normal-map" else x
    for bpp in (0.5, 2.0):
        data = bandelets.encode(x, bpp=bpp, kind=kind)
        header, streams = unpack(data)
        plain = pack(replace(header, restoration=0), streams)
        restored = metrics.psnr(reference, bandelets.decode(data), kind)
        assert restored >= metrics.psnr(reference, bandelets.decode(plain), kind)


def test_no_restoration_with_local_frames():
    v, u = np.mgrid[0:32, 0:32] / 31.0
    surface = np.stack([np.cos(3 * u), np.sin(2 * v), u * v], axis=-1)
    data = bandelets.encode(surface, bpp=4.0, kind="geometry-image", frames=True)
    assert unpack(data)[0].restoration == 0


def test_psnr_target_counts_the_restoration(crease_map):
    """A quality target is met by the restored image, with a smaller file than without it."""
    restored = codec.encode_with_stats(crease_map, psnr=45.0, kind="normal-map")
    plain = codec.encode_with_stats(crease_map, psnr=45.0, kind="normal-map", restore=False)
    decoded = metrics.psnr(crease_map, bandelets.decode(restored.data), "normal-map")
    assert decoded >= 45.0
    assert restored.psnr == pytest.approx(decoded, abs=1e-9)  # what rate control trusted
    assert len(restored.data) < len(plain.data)
