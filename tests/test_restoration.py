"""Decoder-side restoration (bandelets.restore.restoration) and its place in the codec."""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest

import bandelets
from bandelets import metrics
from bandelets.codec import decoder, encoder, restoring
from bandelets.codec.options import EncodeOptions
from bandelets.format.header import pack, unpack
from bandelets.format.quantizer import bin_bounds, dequantize, quantize
from bandelets.restore import restoration
from bandelets.transform.wavelets import wavedec, waverec


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
        low, high = bin_bounds(bins, t)
        assert np.all((low <= x) & (x <= high))
        assert np.all(high - low <= 4 * t)
        # The plain reconstruction lies in its own bin.
        r = dequantize(bins, t)
        assert np.all((low <= r) & (r <= high))


def _log_penalty(squared_norm, smoothing, edge):
    n = np.sqrt(squared_norm + smoothing**2)
    return np.sum(edge * np.log1p(n / edge))


def _penalty(x, smoothing, edge, second_order=0.0, second_edge=1.0, folded=False, second_across=False):
    """The restoration penalty written plainly with numpy, from its definition."""
    rows, cols = x.shape[1:]
    dx = np.diff(x, axis=2, append=x[:, :, -1:])
    dy = np.diff(x, axis=1, append=x[:, -1:, :])
    first = _log_penalty(np.sum(dx**2 + dy**2, axis=0), smoothing, edge)
    xx, yy, xy = (np.zeros_like(x) for _ in range(3))
    xx[:, :, 1:-1] = np.diff(x, 2, axis=2)
    yy[:, 1:-1, :] = np.diff(x, 2, axis=1)
    xy[:, :-1, :-1] = np.diff(np.diff(x, axis=1), axis=2)
    second = _log_penalty(np.sum(xx**2 + yy**2 + 2 * xy**2, axis=0), smoothing, second_edge)
    if folded:  # each pair of pixels glued across an edge once, as on the sphere
        pairs = [((e, j), (e, cols - 1 - j)) for e in (0, rows - 1) for j in range(cols // 2)]
        pairs += [((i, e), (rows - 1 - i, e)) for e in (0, cols - 1) for i in range(rows // 2)]
        across = np.array([x[:, p[0], p[1]] - x[:, q[0], q[1]] for p, q in pairs])
        first += _log_penalty(np.sum(across**2, axis=1), smoothing, edge)
    if second_across:  # centred on every border pixel: its neighbour across the fold, itself, inside
        triples = [
            ((e, j), (e, cols - 1 - j), (n, j))
            for e, n in ((0, 1), (rows - 1, rows - 2))
            for j in range(cols)
        ]
        triples += [
            ((i, e), (rows - 1 - i, e), (i, n))
            for e, n in ((0, 1), (cols - 1, cols - 2))
            for i in range(rows)
        ]
        folds = np.array([x[:, f[0], f[1]] - 2 * x[:, p[0], p[1]] + x[:, n[0], n[1]] for p, f, n in triples])
        second += _log_penalty(np.sum(folds**2, axis=1), smoothing, second_edge)
    return first + second_order * second


# A log total variation; the total variation; each with a log penalty on the second differences;
# with the differences across the folds of an octahedral geometry image (odd and even sides), and
# the second differences across them (a folded normal map).
@pytest.mark.parametrize(
    "edge, second_order, folded, second_across, shape",
    [
        (0.05, 0.0, False, False, (2, 5, 7)),
        (1e6, 0.0, False, False, (2, 5, 7)),
        (0.05, 0.3, False, False, (2, 5, 7)),
        (1e6, 2.0, False, False, (2, 5, 7)),
        (0.05, 0.3, True, False, (2, 5, 7)),
        (0.05, 0.3, True, False, (3, 6, 6)),
        (0.05, 0.3, True, True, (2, 5, 7)),
        (0.05, 0.3, True, True, (3, 6, 6)),
        (0.05, 0.0, True, True, (2, 6, 6)),
    ],
)
def test_penalty_gradient_is_the_derivative(rng, edge, second_order, folded, second_across, shape):
    x = rng.random(shape)
    gradient = restoration.penalty_gradient(
        x, 0.1, edge, second_order, 0.2, folded=folded, second_across=second_across
    )
    h = 1e-6
    numeric = np.zeros_like(x)
    for index in np.ndindex(x.shape):
        step = np.zeros_like(x)
        step[index] = h
        up, down = (
            _penalty(x + s, 0.1, edge, second_order, 0.2, folded, second_across) for s in (step, -step)
        )
        numeric[index] = (up - down) / (2 * h)
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("shape", [(3, 9, 6), (1, 8, 5), (2, 33, 17)])
@pytest.mark.parametrize("folded, second_across", [(False, False), (True, False), (True, True)])
def test_the_gradient_in_two_threads_is_the_same_numbers(rng, monkeypatch, shape, folded, second_across):
    """The rows split in two halves (each with the rows its stencils reach past the cut) give
    the same bits as one piece: the restoration's output must not depend on the thread count."""
    x = rng.standard_normal(shape)
    monkeypatch.setattr(restoration, "THREADED_SAMPLES", 2**62)
    whole = restoration.penalty_gradient(x, 0.01, 0.1, 0.5, 0.2, folded=folded, second_across=second_across)
    monkeypatch.setattr(restoration, "THREADED_SAMPLES", 0)
    monkeypatch.setattr(restoration, "CORES", 2)
    halves = restoration.penalty_gradient(x, 0.01, 0.1, 0.5, 0.2, folded=folded, second_across=second_across)
    assert np.array_equal(whole, halves)


def test_the_second_order_term_prefers_constant_slopes():
    """A ramp costs the second-order term nothing; the same ramp bent in the middle costs it."""

    def second_order_gradient(x):
        return restoration.penalty_gradient(x, 1e-4, 1e6, 1.0, 0.05) - restoration.penalty_gradient(
            x, 1e-4, 1e6
        )

    ramp = np.broadcast_to(np.arange(8.0) * 0.1, (1, 4, 8)).copy()
    assert np.abs(second_order_gradient(ramp)).max() < 1e-9
    bent = ramp.copy()
    bent[:, :, 4:] += 0.05 * np.arange(4)
    assert np.abs(second_order_gradient(bent)).max() > 0.1


def test_the_penalty_keeps_a_crease_and_flattens_ripples():
    """Where the gradient is far above ``edge`` the pull is far weaker than on a small ripple."""
    x = np.zeros((1, 4, 8))
    x[0, :, 4:] = 1.0  # a crease between columns 3 and 4
    x[0, :, 1] += 0.01  # a ripple
    g = restoration.penalty_gradient(x, 1e-4, 0.05)
    assert abs(g[0, 1, 3]) < 0.1 * abs(g[0, 1, 1])


def test_iterations_stay_consistent_with_the_bins(edge_image):
    """Each step that projects keeps every coefficient of an orthogonal transform inside its bin,
    and the first estimate is the plain dequantized image."""
    t = 0.05

    def analysis(x):
        return wavedec(x[0], "db4", 3)[None]

    def synthesis(c):
        return waverec(c[0], "db4", 3)[None]

    q = quantize(analysis(edge_image[None])[0], t)
    low, high = bin_bounds(q, t)
    steps = restoration.iterate([q], t, analysis, synthesis)
    first = next(steps)[0].copy()
    np.testing.assert_allclose(first, synthesis(dequantize(q, t)[None])[0])
    # Every PROJECT_EVERY steps the image is projected into the bins.
    for _ in range(restoration.PROJECT_EVERY):
        x = next(steps)[0]
    c = analysis(x[None])[0]
    assert np.all((c >= low - 1e-9) & (c <= high + 1e-9))
    assert not np.allclose(x, first)
    # Smoother than where it started: the penalty went down.
    constants = (restoration.EDGE * t, restoration.SECOND_ORDER, restoration.SECOND_EDGE * t)
    assert _penalty(x[None], 1e-9, *constants) < _penalty(first[None], 1e-9, *constants)


def test_restoration_improves_a_crease_map_at_no_cost(crease_map):
    # Without the loop filter, whose section is fitted to each decoded image (a byte more or less).
    # The channels pinned: a restored rate target may also try their Riesz pair and keep the better.
    options = {"bpp": 1.0, "kind": "normal-map", "loop_filter": False, "riesz": False}
    plain = bandelets.encode(crease_map, restore=False, **options)
    data = bandelets.encode(crease_map, **options)
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
    trees, quantized, lifting = decoder.decoded_bins(header, streams)
    transforms = decoder.channel_transforms(header, trees, quantized, lifting)

    def best(unit_vectors):
        steps = restoration.iterate(quantized, header.threshold, *transforms, unit_vectors=unit_vectors)
        return max(
            metrics.psnr(normals, decoder.decoded_image(next(steps), header), "normal-map") for _ in range(30)
        )

    assert best((64, 64)) > best(None) + 0.05


@pytest.mark.parametrize("kind", ["image", "normal-map"])
def test_the_encoder_never_picks_a_worse_restoration(rng, kind):
    """On noise, restoring may not help: the count chosen never decodes worse than none (both
    without the loop filter, which is fitted to the restored image and chosen after the count)."""
    x = rng.normal(size=(48, 40, 3))
    if kind == "normal-map":
        x = metrics.unit_vectors(x)
    reference = metrics.unit_vectors(x) if kind == "normal-map" else x
    for bpp in (0.5, 2.0):
        header, streams = unpack(bandelets.encode(x, bpp=bpp, kind=kind))
        header = replace(header, loop_filter=None)
        plain = pack(replace(header, restoration=0), streams)
        restored = metrics.psnr(reference, bandelets.decode(pack(header, streams)), kind)
        assert restored >= metrics.psnr(reference, bandelets.decode(plain), kind)


def test_files_with_local_frames_are_restored_in_their_frames():
    """The bins hold the coefficients turned into the local frames: each projection keeps the
    restored image's coefficients, turned the same way, in them; step 0 is the plain decoding."""
    v, u = np.mgrid[0:32, 0:32] / 31.0
    surface = np.stack([np.cos(3 * u), np.sin(2 * v), u * v], axis=-1)
    data = bandelets.encode(surface, bpp=4.0, kind="geometry-image", frames=True, restore=False)
    header, streams = unpack(data)
    assert header.frames
    trees, quantized, lifting = decoder.decoded_bins(header, streams)
    analysis, synthesis = decoder.channel_transforms(header, trees, quantized, lifting)
    steps = restoration.iterate(quantized, header.threshold, analysis, synthesis)
    np.testing.assert_array_equal(decoder.decoded_image(next(steps), header), bandelets.decode(data))
    for _ in range(restoration.PROJECT_EVERY):  # a step that projects into the bins
        x = next(steps)
    c = analysis(x.astype(np.float64))  # the steps' images are float32 here
    for k, q in enumerate(quantized):
        low, high = bin_bounds(q, header.threshold)
        assert np.all((c[k] >= low - 1e-9) & (c[k] <= high + 1e-9))


def test_psnr_target_counts_the_restoration(crease_map):
    """A quality target is met by the restored image, with a smaller file than without it."""
    restored = encoder.encode_with_stats(crease_map, EncodeOptions(kind="normal-map"), psnr=45.0)
    plain = encoder.encode_with_stats(crease_map, EncodeOptions(kind="normal-map", restore=False), psnr=45.0)
    decoded = metrics.psnr(crease_map, bandelets.decode(restored.data), "normal-map")
    assert decoded >= 45.0
    assert restored.psnr == pytest.approx(decoded, abs=1e-9)  # what rate control trusted
    assert len(restored.data) < len(plain.data)


def test_channels_transformed_in_threads_decode_the_same(monkeypatch, crease_map):
    """Large images transform their channels in parallel threads: same result as one by one."""
    data = bandelets.encode(crease_map, bpp=1.0, kind="normal-map")
    assert unpack(data)[0].restoration > 0
    alone = bandelets.decode(data)
    monkeypatch.setattr(decoder, "THREADS_FROM", 0)
    np.testing.assert_array_equal(bandelets.decode(data), alone)


def test_decoding_and_measuring_start_no_threads_once_the_workers_are_there(monkeypatch, crease_map):
    """The steps' halves, the channels' transforms and the encoder's measure share the process's
    worker threads (restoration.workers): after a first decode, more decodes and measures start no
    thread (one per call took a quarter of the restoration search on a loaded 2-core machine)."""
    for module, name in [(restoration, "CORES"), (metrics, "CORES"), (restoration, "THREADED_SAMPLES")]:
        monkeypatch.setattr(module, name, 2 if name == "CORES" else 0)
    monkeypatch.setattr(metrics, "THREADED_PIXELS", 0)
    monkeypatch.setattr(decoder, "THREADS_FROM", 0)
    data = bandelets.encode(crease_map, bpp=1.0, kind="normal-map")
    measure = metrics.psnr_of_channels(crease_map, "normal-map", equidistant=True)
    bandelets.decode(data)
    started = []
    start = threading.Thread.start
    monkeypatch.setattr(threading.Thread, "start", lambda thread: started.append(thread) or start(thread))
    for _ in range(2):
        decoded = bandelets.decode(data)
        measure(np.zeros((2, 64, 64), np.float32))
    assert started == []
    monkeypatch.undo()
    np.testing.assert_array_equal(decoded, bandelets.decode(data))


@pytest.mark.parametrize("facing_away", [False, True])
def test_the_encoders_measure_is_the_psnr_of_the_decoded_image(crease_map, facing_away):
    """metrics.psnr_of_channels, which the encoder's search uses on every iteration, gives the PSNR
    of what decode returns, for two channels (equidistant coordinates) and three."""
    normals = crease_map.copy()
    if facing_away:
        normals[:, :32, 2] *= -1
    data = bandelets.encode(normals, bpp=0.5, kind="normal-map", restore=False)
    header, streams = unpack(data)
    assert header.channels == (3 if facing_away else 2)
    trees, quantized, lifting = decoder.decoded_bins(header, streams)
    measure = metrics.psnr_of_channels(normals, "normal-map", equidistant=not facing_away)
    for _, channels in zip(range(3), decoder.restorations(header, trees, quantized, lifting), strict=False):
        decoded = metrics.psnr(normals, decoder.decoded_image(channels, header), "normal-map")
        assert measure(channels) == pytest.approx(decoded, abs=1e-9)


@pytest.mark.parametrize("scale, dtype", [(1.0, np.float32), (1e6, np.float64)])
def test_the_steps_images_are_float32_where_the_scale_allows(edge_image, scale, dtype):
    """float32 between the steps where the samples are at most SINGLE_UP_TO T (their rounding far
    below a step's moves), float64 otherwise; the first image is float64 either way."""
    t = 0.05

    def analysis(x):
        return wavedec(np.asarray(x[0], np.float64), "db4", 3)[None]

    def synthesis(c):
        return waverec(c[0], "db4", 3)[None]

    q = quantize(analysis(scale * edge_image[None])[0], t)
    steps = restoration.iterate([q], t, analysis, synthesis)
    assert next(steps).dtype == np.float64
    assert next(steps).dtype == dtype


def test_the_encoder_writes_the_fewest_iterations_that_keep_the_share(crease_map):
    """Not the best count: the first that keeps RESTORATION_SHARE of the best gain (the best one
    only where the gain rises that steeply to its peak, as on this map since format version 12)."""
    data = bandelets.encode(crease_map, bpp=1.0, kind="normal-map", restore=False)
    header, streams = unpack(data)
    trees, quantized, lifting = decoder.decoded_bins(header, streams)
    measure = metrics.psnr_of_channels(crease_map, "normal-map", equidistant=True)
    steps = decoder.restorations(header, trees, quantized, lifting)
    scores = np.array([measure(next(steps)) for _ in range(80)])
    gains = scores - scores[0]
    chosen = unpack(bandelets.encode(crease_map, bpp=1.0, kind="normal-map"))[0].restoration
    assert 0 < chosen <= np.argmax(gains)
    assert gains[chosen] >= restoring.RESTORATION_SHARE * gains.max() > gains[chosen - 1]
