"""The octahedral unfolding: inverse, equal area, border gluing."""

import numpy as np

from bandelets.surfaces.octahedral import grid, sphere_to_square, square_to_sphere


def _sphere_points(n=20000, seed=0):
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def test_map_and_inverse_agree():
    p = _sphere_points()
    assert np.abs(square_to_sphere(sphere_to_square(p)) - p).max() < 1e-12
    uv = grid(64).reshape(-1, 2)
    assert np.abs(sphere_to_square(square_to_sphere(uv)) - uv).max() < 1e-12
    assert np.allclose(np.linalg.norm(square_to_sphere(uv), axis=1), 1.0)


def test_equal_area():
    uv = sphere_to_square(_sphere_points(200_000, seed=1))
    counts, _, _ = np.histogram2d(uv[:, 0], uv[:, 1], bins=4, range=[[-1, 1], [-1, 1]])
    assert np.all(np.abs(counts / counts.mean() - 1) < 0.03)


def test_border_glued_to_itself_reversed():
    t = np.linspace(-1, 1, 41)
    one = np.ones_like(t)
    for edge in (
        np.stack([t, -one], 1),
        np.stack([t, one], 1),
        np.stack([-one, t], 1),
        np.stack([one, t], 1),
    ):
        mirrored = edge.copy()
        mirrored[:, np.argmax(np.ptp(edge, axis=0))] *= -1
        assert np.abs(square_to_sphere(edge) - square_to_sphere(mirrored)).max() < 1e-12
    corners = square_to_sphere(np.array([[1.0, 1], [-1, 1], [1, -1], [-1, -1]]))
    assert np.allclose(corners, [0, 0, -1])
