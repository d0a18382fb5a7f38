"""The decoder's quadric decimation of a geometry image's grid: fast-simplification, MeshLab's
collapse where that one does not arrive at a closed genus-0 mesh of the asked count."""

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("pymeshlab")
pytest.importorskip("fast_simplification")

from bandelets.surfaces import geometry_image  # noqa: E402
from bandelets.surfaces.checks import check_genus0  # noqa: E402
from bandelets.surfaces.codec import make_geometry_image  # noqa: E402
from bandelets.surfaces.metrics import hausdorff_psnr  # noqa: E402


@pytest.fixture(autouse=True)
def fast_on_small_grids(monkeypatch):
    """fast-simplification on these small grids too (by default from 512 x 512 only)."""
    monkeypatch.setattr(geometry_image, "FAST_FROM", 0)


@pytest.fixture(scope="module")
def bumpy():
    """A bumpy ellipsoid (642 vertices) and the glued mesh of its 64 x 64 geometry image."""
    mesh = trimesh.creation.icosphere(subdivisions=3)
    direction = mesh.vertices / np.linalg.norm(mesh.vertices, axis=1, keepdims=True)
    mesh.vertices *= (1.0 + 0.1 * np.sin(5 * direction[:, 0]) * np.cos(4 * direction[:, 1]))[:, None]
    mesh.vertices *= (1.0, 0.7, 1.3)
    return mesh, geometry_image.mesh_from_image(make_geometry_image(mesh, 64).positions)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_fast_decimation_arrives_at_the_count_in_any_unit(bumpy, scale, monkeypatch):
    mesh, grid = bumpy
    grid = trimesh.Trimesh(grid.vertices * scale, grid.faces, process=False)

    def refuse(*args):  # MeshLab must not be needed here
        raise AssertionError("fell back to MeshLab")

    monkeypatch.setattr(geometry_image, "decimate_meshlab", refuse)
    decimated = geometry_image.decimate(grid, 642)
    assert len(decimated.vertices) == 642 and len(decimated.faces) == 2 * 642 - 4
    check_genus0(decimated.vertices, decimated.faces)
    assert decimated.is_watertight and decimated.volume > 0  # closed, facing out
    reference = trimesh.Trimesh(mesh.vertices * scale, mesh.faces, process=False)
    assert hausdorff_psnr(reference, decimated, samples=20_000) > 45.0


def test_fast_decimation_keeps_meshlabs_quality(bumpy):
    mesh, grid = bumpy
    fast = hausdorff_psnr(mesh, geometry_image.decimate(grid, 642), samples=50_000)
    meshlab = hausdorff_psnr(mesh, geometry_image.decimate_meshlab(grid, 642), samples=50_000)
    assert fast > meshlab - 0.5


def test_meshlab_decimates_small_grids(bumpy, monkeypatch):
    mesh, grid = bumpy
    monkeypatch.setattr(geometry_image, "FAST_FROM", len(grid.vertices) + 1)
    import fast_simplification

    def refuse(*args, **kwargs):
        raise AssertionError("fast-simplification on a small grid")

    monkeypatch.setattr(fast_simplification, "simplify", refuse)
    calls = []
    meshlab = geometry_image.decimate_meshlab
    monkeypatch.setattr(geometry_image, "decimate_meshlab", lambda *a: calls.append(a[1]) or meshlab(*a))
    assert len(geometry_image.decimate(grid, 642).vertices) == 642 and calls == [642]


def test_meshlab_takes_over_where_fast_simplification_stops_short(bumpy, monkeypatch):
    mesh, grid = bumpy
    calls = []
    meshlab = geometry_image.decimate_meshlab

    def counted(*args):
        calls.append(args[1])
        return meshlab(*args)

    monkeypatch.setattr(geometry_image, "decimate_meshlab", counted)
    monkeypatch.setattr(geometry_image, "AGGRESSIVENESS", (0.0,))  # a threshold that never grows
    decimated = geometry_image.decimate(grid, 300)
    assert calls == [300] and len(decimated.vertices) == 300
    check_genus0(decimated.vertices, decimated.faces)
