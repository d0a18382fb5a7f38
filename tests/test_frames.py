"""Local frames of geometry images (bandelets.transform.frames) and their use by the codec."""

from __future__ import annotations

import numpy as np
import pytest

import bandelets
from bandelets import metrics
from bandelets.codec.encoder import encode_with_stats
from bandelets.codec.options import EncodeOptions
from bandelets.format.fields import NORMAL_MAP_WEIGHT
from bandelets.format.header import unpack
from bandelets.surfaces import octahedral
from bandelets.transform import frames
from bandelets.transform.wavelets import wavedec


def _bumpy_sphere(side: int) -> np.ndarray:
    """Positions of a bumped sphere on the octahedral grid (a spherical geometry image)."""
    p = octahedral.square_to_sphere(octahedral.grid(side))
    return p * (1.0 + 0.1 * np.sin(3.0 * p[..., :1]) * p[..., 1:2])


def _tangents(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.gradient(positions, axis=1), np.gradient(positions, axis=0)


def _random_rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    return q * np.sign(np.diag(r))


def test_frames_are_orthonormal_and_right_handed():
    f = frames.frame_field(*_tangents(_bumpy_sphere(32)))
    eye = np.einsum("...ij,...kj->...ik", f, f)
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(3), eye.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(f), 1.0, atol=1e-12)


def test_the_normal_of_a_plane_is_its_normal(rng):
    rotation = _random_rotation(rng)
    v, u = np.mgrid[0:16, 0:16].astype(np.float64)
    plane = np.stack([u + 0.1 * v**2, v, np.zeros_like(u)], axis=-1) @ rotation.T
    normal = frames.frame_field(*_tangents(plane))[..., 0, :]
    np.testing.assert_allclose(np.abs(normal @ rotation[:, 2]), 1.0, atol=1e-12)


def test_degenerate_places_get_a_fixed_frame():
    line = np.zeros((8, 8, 3))
    line[..., 0] = np.arange(8)[None, :]  # the rows collapse: no normal anywhere
    fixed = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # normal z, tangents x, y
    np.testing.assert_array_equal(frames.frame_field(*_tangents(line)), np.broadcast_to(fixed, (8, 8, 3, 3)))


def test_a_warped_tilted_plane_has_no_normal_details(rng):
    # Sliding points along a plane changes the position channels, never the normal component.
    rotation = _random_rotation(rng)
    v, u = np.mgrid[0:64, 0:64].astype(np.float64) / 64
    warped = np.stack([u + 0.05 * np.sin(6 * v), v + 0.05 * np.cos(5 * u), np.zeros_like(u)], -1)
    image = warped @ rotation.T + 0.3
    levels = 3
    coefficients = [wavedec(image[..., k], "cdf97", levels) for k in range(3)]
    local = [c.copy() for c in coefficients]
    for level in range(levels, 0, -1):
        frame = frames.level_frames(coefficients, level, "cdf97", levels, "symmetric")
        frames.rotate(local, frame, level, levels, 3.0, local=True)
    details = np.ones(image.shape[:2], bool)
    details[: 64 >> levels, : 64 >> levels] = False
    tangential = np.hypot(local[1][details], local[2][details])
    assert np.abs(local[0][details]).max() < 1e-9 * tangential.max()
    # and the decoder's order of turning back restores every coefficient
    frames.to_global(local, "cdf97", levels, "symmetric", 3.0)
    for b, c in zip(local, coefficients, strict=True):
        np.testing.assert_allclose(b, c, rtol=0, atol=1e-12)


def _sphere_normals(side: int) -> np.ndarray:
    """Unit normals facing every way: those of the octahedral sphere, bumped."""
    p = _bumpy_sphere(side)
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


def test_normal_map_frames_are_orthonormal_around_the_normals(rng):
    normals = rng.normal(size=(50, 3)) * rng.uniform(0.1, 3.0, size=(50, 1))
    normals[:3] = [[1.0, 0.0, 0.0], [-2.0, 1e-5, 0.0], [0.0, 0.0, 0.0]]  # along x; zero
    f = frames.normal_map_frames(normals)
    eye = np.einsum("...ij,...kj->...ik", f, f)
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(3), eye.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(f), 1.0, atol=1e-12)
    np.testing.assert_allclose(f[3:, 0], normals[3:] / np.linalg.norm(normals[3:], axis=-1, keepdims=True))
    np.testing.assert_array_equal(f[2, 0], [0.0, 0.0, 1.0])


def test_the_details_of_a_normal_map_are_nearly_tangent():
    """In the frames of the coarse normals, the normal component of the details is a small
    fraction of the tangential ones (second order), and turning back restores them all."""
    normals = _sphere_normals(64)
    levels = 3
    coefficients = [wavedec(normals[..., k], "cdf97", levels) for k in range(3)]
    local = [c.copy() for c in coefficients]
    for level in range(levels, 0, -1):
        frame = frames.level_frames(coefficients, level, "cdf97", levels, "symmetric", "normal-map")
        frames.rotate(local, frame, level, levels, 1.0, local=True)
    details = np.ones(normals.shape[:2], bool)
    details[: 64 >> levels, : 64 >> levels] = False
    energy = [np.sum(c[details] ** 2) for c in local]
    assert energy[0] < 0.05 * (energy[1] + energy[2])
    frames.to_global(local, "cdf97", levels, "symmetric", 1.0, "normal-map")
    for b, c in zip(local, coefficients, strict=True):
        np.testing.assert_allclose(b, c, rtol=0, atol=1e-12)


def test_the_first_tangent_follows_a_crease():
    """At an oblique crease between two flat facets, the frames' first tangent
    turns from one facet's normal towards the other's: the details there fill one tangential
    channel and leave the other nearly empty (with the x axis projected they fill both)."""
    side, levels = 64, 3
    a, b = np.array([0.0, 0.6, 0.8]), np.array([0.6, 0.0, 0.8])  # they differ at 45 degrees to x
    y, x = np.mgrid[0:side, 0:side]
    ramp = np.clip((x - 0.6 * y - 12.0) / 4.0, 0.0, 1.0)[..., None]  # a few pixels wide
    normals = metrics.unit_vectors((1 - ramp) * a + ramp * b)
    coefficients = [wavedec(normals[..., k], "cdf97", levels) for k in range(3)]
    frame = frames.level_frames(coefficients, 1, "cdf97", levels, "symmetric", "normal-map")
    n = frame[..., 0, :]
    near = np.minimum(np.linalg.norm(n - a, axis=-1), np.linalg.norm(n - b, axis=-1)) > 0.05
    assert near.sum() > 20  # the places whose coarse normal lies between the facets'
    across = (b - a) - np.sum((b - a) * frame[..., 0, :], axis=-1, keepdims=True) * frame[..., 0, :]
    cosine = np.abs(np.sum(across * frame[..., 1, :], axis=-1)) / np.linalg.norm(across, axis=-1)
    assert np.min(cosine[near]) > 0.99
    energies = []
    for aligned in (True, False):
        local = [c.copy() for c in coefficients]
        f = frame if aligned else frames.normal_map_frames(frame[..., 0, :])
        frames.rotate(local, f, 1, levels, 1.0, local=True)
        finest = [c[side // 2 :, side // 2 :] for c in local]
        energies.append([np.sum(c**2) for c in finest])
    (_, first, second), (_, x_first, x_second) = energies
    assert second < 0.01 * first and min(x_first, x_second) > 0.05 * (x_first + x_second)


def test_normal_maps_of_three_channels_are_coded_in_local_frames():
    normals = _sphere_normals(64)
    data = bandelets.encode(normals, bpp=1.0, kind="normal-map")
    header = unpack(data)[0]
    assert (header.channels, header.frames, header.normal_weight) == (3, True, NORMAL_MAP_WEIGHT)
    assert metrics.psnr(normals, bandelets.decode(data), "normal-map") > 35


@pytest.mark.parametrize("transform", ["bandelet", "wavelet"])
@pytest.mark.parametrize("extension", ["symmetric", "spherical"])
def test_geometry_image_with_local_frames_round_trips(transform, extension):
    image = _bumpy_sphere(32)
    options = EncodeOptions(
        kind="geometry-image", transform=transform, frames=True, normal_weight=2.5, extension=extension
    )
    enc = encode_with_stats(image, options, threshold=2e-3)
    header, _ = unpack(enc.data)
    assert (header.frames, header.normal_weight, header.extension) == (True, 2.5, extension)
    decoded = bandelets.decode(enc.data)
    error = float(np.sum((decoded - image) ** 2))
    # The coefficients' error is the image's (up to the non-orthogonality of cdf97).
    assert error == pytest.approx(enc.coefficient_sse, rel=0.15)
    assert np.abs(decoded - image).max() < 20 * 2e-3


def test_the_weight_moves_the_error_out_of_the_normals():
    image = _bumpy_sphere(64)
    normals = frames.frame_field(*_tangents(image))[..., 0, :]
    split = {}
    for weight in (1.0, 4.0):
        # The coefficients' error, without the loop filter (which reshapes it after the fact).
        data = bandelets.encode(
            image, bpp=2.0, kind="geometry-image", frames=True, normal_weight=weight, loop_filter=False
        )
        error = bandelets.decode(data) - image
        along = np.einsum("...k,...k->...", error, normals)
        split[weight] = np.sum(along**2) / np.sum(error**2)
    assert split[4.0] < 0.5 * split[1.0]


def test_spherical_extension_picks_levels_that_divide_the_side():
    image = _bumpy_sphere(34)
    header, _ = unpack(bandelets.encode(image, threshold=1e-2, kind="geometry-image", extension="spherical"))
    assert header.levels == 1
    decoded = bandelets.decode(
        bandelets.encode(image, threshold=1e-4, kind="geometry-image", extension="spherical")
    )
    assert np.abs(decoded - image).max() < 1e-3


@pytest.mark.parametrize(
    ("array", "options", "words"),
    [
        (np.zeros((16, 16, 3)), {"kind": "normal-map", "frames": True}, "geometry images only"),
        (np.zeros((16, 16)), {"kind": "image", "extension": "spherical"}, "geometry images only"),
        (np.zeros((16, 32, 3)), {"kind": "geometry-image", "extension": "spherical"}, "square"),
        (np.zeros((16, 16, 3)), {"kind": "geometry-image", "extension": "mirror"}, "unknown extension"),
        (
            np.zeros((16, 16, 3)),
            {"kind": "geometry-image", "frames": True, "normal_weight": 0.0},
            "1/64 to 64",
        ),
        (np.zeros((16, 16, 3)), {"kind": "geometry-image", "frames": True, "normal_weight": np.nan}, "1/64"),
    ],
)
def test_bad_geometry_options_are_refused(array, options, words):
    with pytest.raises(ValueError, match=words):
        bandelets.encode(array, threshold=0.1, **options)


def test_memory_estimate_covers_the_decoding_with_frames():
    import tracemalloc

    from bandelets.format.limits import decoder_memory

    data = bandelets.encode(
        _bumpy_sphere(128), bpp=2.0, kind="geometry-image", frames=True, transform="wavelet"
    )
    header = unpack(data)[0]
    assert header.restoration > 0
    for restore in (False, True):
        bandelets.decode(data, restore=restore)
        tracemalloc.start()
        bandelets.decode(data, restore=restore)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak <= decoder_memory(128, 128, 3, header.levels, frames=True, restoration=restore)
