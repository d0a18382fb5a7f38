"""The generated test surfaces of issue 3: the paper's functional model and the bump map."""

from __future__ import annotations

import numpy as np
import pytest

from bandelets.format.samples import from_samples
from bandelets.samples import (
    bevel_normal_map,
    blurred_edge,
    bump_normal_map,
    crease_height,
    crease_normal_map,
    normal_map,
)


@pytest.mark.parametrize("profile", ["step", "tangent"])
def test_blurred_edge_is_deterministic_and_seeded(profile):
    a = blurred_edge(48, profile)
    assert a.shape == (48, 48) and a.dtype == np.float64 and np.all(np.isfinite(a))
    assert np.array_equal(a, blurred_edge(48, profile))
    assert not np.allclose(a, blurred_edge(48, profile, seed=1))
    assert 0.0 <= a.min() and a.max() <= 1.0


def test_the_step_is_sharp_at_the_left_and_blurred_at_the_right():
    jumps = np.abs(np.diff(blurred_edge(128, "step"), axis=0))
    assert jumps[:, :16].max() > 0.2  # close to the full step of 0.35 in one pixel
    assert jumps[:, -16:].max() < 0.05  # spread over several pixels


def test_the_tangent_edge_is_continuous_but_kinked():
    f = blurred_edge(128, "tangent")
    assert np.abs(np.diff(f, axis=0)).max() < 0.03  # no step
    second = np.abs(np.diff(f, n=2, axis=0))
    assert second[:, :16].max() > 10 * np.median(second)  # the slope jumps at the sharp end


def test_unknown_profile():
    with pytest.raises(ValueError, match="profile"):
        blurred_edge(16, "ramp")


def test_bump_normal_map_is_seeded_unit_vectors():
    n = bump_normal_map(64)
    assert n.shape == (64, 64, 3)
    assert np.allclose(np.linalg.norm(n, axis=-1), 1.0) and n[..., 2].min() > 0.5
    assert np.array_equal(n, bump_normal_map(64)) and not np.allclose(n, bump_normal_map(64, seed=3))


def test_normal_map_of_a_plane_is_its_constant_normal():
    n = normal_map(lambda x, y: 0.5 * x - 0.25 * y, 16)
    expected = np.array([-0.5, 0.25, 1.0]) / np.linalg.norm([-0.5, 0.25, 1.0])
    assert np.allclose(n, expected, atol=1e-6)
    assert crease_normal_map(16).shape == (16, 16, 3)
    assert crease_height(np.zeros(1), np.zeros(1)).shape == (1,)


def test_bevel_map_is_8_bit_samples_on_an_exactly_flat_background():
    px = bevel_normal_map(128)
    assert px.shape == (128, 128, 3) and px.dtype == np.uint8
    assert np.array_equal(px, bevel_normal_map(128))  # deterministic
    flat = np.all(px == (128, 128, 255), axis=-1)
    assert 0.5 < flat.mean() < 0.75  # the background; the shapes take the rest
    assert flat[0, 0] and flat[-1, -1]
    n = from_samples(px, "normal-map", 8)
    assert np.all(np.abs(np.linalg.norm(n, axis=-1) - 1.0) < 0.01)  # unit vectors, as rounded
    tilt = np.degrees(np.arccos(np.clip(n[..., 2] / np.linalg.norm(n, axis=-1), -1, 1)))
    assert 40 < np.percentile(tilt[~flat], 99) < 70  # the 45-degree chamfers and rounded bevels
    # The tops of the shapes: flat without the texture, bumpy (a little) with it.
    faces = ~flat & np.all(bevel_normal_map(128, texture=0.0) == (128, 128, 255), axis=-1)
    assert faces.sum() > 0.15 * (~flat).sum()
    assert 0.005 < np.std(n[faces, 0]) < 0.1
    assert not np.array_equal(px, bevel_normal_map(128, seed=1))


def test_bevel_map_size_is_checked():
    with pytest.raises(ValueError, match="at least 16"):
        bevel_normal_map(8)
