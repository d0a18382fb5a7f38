"""Object-space normal maps rendered from meshes (bandelets.surfaces.render), and the coder on
their empty background (zero vectors)."""

from __future__ import annotations

import numpy as np
import pytest

import bandelets
from bandelets.metrics import psnr
from bandelets.surfaces.render import corner_normals, render_normals, to_samples, turned_up

trimesh = pytest.importorskip("trimesh")


def _box():
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    return np.asarray(box.vertices), np.asarray(box.faces)


def test_a_box_seen_from_above_is_its_top_face_on_the_background():
    vertices, faces = _box()
    normals = render_normals(vertices, faces, 64, crease_angle=45.0, margin=0.125, background=(0, 0, 0))
    # The box spans 48 of the 64 columns (2 wide) and 24 rows (1 deep), centred.
    assert np.array_equal(normals[20:44, 8:56], np.broadcast_to([0.0, 0.0, 1.0], (24, 48, 3)))
    empty = np.ones((64, 64), bool)
    empty[20:44, 8:56] = False
    assert np.array_equal(normals[empty], np.zeros((empty.sum(), 3)))
    assert np.array_equal(to_samples(normals)[0, 0], [32768, 32768, 32768])


def test_a_silhouette_pixel_averages_what_it_covers():
    vertices, faces = _box()
    # The box's left edge 7.5 px in: half of pixel 7 is the top face, half background.
    normals = render_normals(vertices, faces, 64, crease_angle=45.0, margin=0.125 - 0.5 / 64)
    assert np.array_equal(normals[32, 6:9], [[0.0, 0.0, 1.0]] * 3)  # top face on flat background
    normals = render_normals(
        vertices, faces, 64, crease_angle=45, margin=0.125 - 0.5 / 64, background=(1, 0, 0)
    )
    assert np.array_equal(normals[32, 5:10], [[1, 0, 0], [1, 0, 0], [0.5, 0, 0.5], [0, 0, 1], [0, 0, 1]])
    assert np.array_equal(normals[32, 56:58], [[0.5, 0, 0.5], [1, 0, 0]])


def test_the_crease_angle_splits_sharp_edges_only():
    vertices, faces = _box()
    flat = corner_normals(vertices, faces, 0.0)
    smooth = corner_normals(vertices, faces, 180.0)
    split = corner_normals(vertices, faces, 45.0)
    assert np.allclose(np.linalg.norm(smooth, axis=-1), 1.0)
    # At a box's corners the smooth normal leans out of every face; split at 90 degrees it is the face's.
    assert np.allclose(split, flat)
    assert np.all(np.abs(smooth).min(axis=-1) > 0.1)
    # Flat shading: all three corners of a face share its normal.
    assert np.allclose(flat[:, 0], flat[:, 2])


def test_a_sphere_shaded_smooth_shows_its_radial_normals():
    sphere = trimesh.creation.icosphere(subdivisions=4)
    normals = render_normals(sphere.vertices, sphere.faces, 64, margin=0.0, supersampling=1)
    rows, cols = np.mgrid[0:64, 0:64]
    x, y = (cols + 0.5) / 32 - 1, 1 - (rows + 0.5) / 32
    inside = x * x + y * y < 0.9**2
    expected = np.stack([x, y, np.sqrt(np.clip(1 - x * x - y * y, 0, 1))], -1)
    assert np.degrees(np.arccos(np.clip(np.sum(normals * expected, -1)[inside], -1, 1))).max() < 2.0
    # The oblique view stores object-space normals: seen from +x, the visible ones have x > 0.
    side = render_normals(sphere.vertices, sphere.faces, 32, (1, 0, 0), supersampling=1, background=(0, 0, 0))
    seen = np.linalg.norm(side, axis=-1) > 0
    assert seen.mean() > 0.5 and side[seen][:, 0].min() > -0.2 and side[seen][:, 0].mean() > 0.5


def test_turned_up_is_a_rotation_taking_the_axis_to_z():
    points = np.random.default_rng(0).normal(size=(10, 3))
    for up in ("+x", "-x", "+y", "-y", "+z", "-z"):
        axis = np.eye(3)["xyz".index(up[1])] * (1.0 if up[0] == "+" else -1.0)
        assert np.allclose(turned_up(axis[None], up), [[0.0, 0.0, 1.0]])
        turned = turned_up(points, up)
        assert np.allclose(turned @ turned.T, points @ points.T)  # lengths and angles kept
        assert np.linalg.det(turned_up(np.eye(3), up)) > 0  # no mirror


@pytest.mark.parametrize("depth", [0, 16])
def test_a_map_on_a_zero_background_codes_without_nan(depth):
    sphere = trimesh.creation.icosphere(subdivisions=3)
    normals = render_normals(sphere.vertices, sphere.faces, 64, background=(0.0, 0.0, 0.0))
    array = to_samples(normals) if depth else normals
    decoded = bandelets.decode(bandelets.encode(array, bpp=1.0, kind="normal-map"))
    assert np.all(np.isfinite(decoded))
    reference = normals if not depth else array / 65535.0 * 2.0 - 1.0
    assert psnr(reference, decoded, "normal-map") > 30.0


@pytest.mark.parametrize("keywords", [{"view": (0, 0, 0)}, {"view": (0, 1)}, {"size": 0}, {"margin": 0.5}])
def test_bad_arguments_are_refused(keywords):
    vertices, faces = _box()
    with pytest.raises(ValueError):
        render_normals(vertices, faces, **({"size": 8} | keywords))
