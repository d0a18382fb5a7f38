"""Closed / manifold / connected / genus-0 checks on generated and real bad meshes."""

from pathlib import Path

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")

from bandelets.surfaces.checks import check_genus0  # noqa: E402

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"


def _shared(name: str):
    if not MESHES.is_dir():
        pytest.skip(f"{MESHES} is absent: the real test meshes live beside the project, not in it")
    return trimesh.load(MESHES / name, force="mesh", process=True)


def test_icosphere_passes():
    sphere = trimesh.creation.icosphere(subdivisions=2)
    check_genus0(sphere.vertices, sphere.faces)


def test_open_boundary():
    sphere = trimesh.creation.icosphere(subdivisions=2)
    with pytest.raises(ValueError, match="not closed: open boundary of 3 edges"):
        check_genus0(sphere.vertices, sphere.faces[1:])


def test_torus_genus():
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    with pytest.raises(ValueError, match="genus 1"):
        check_genus0(torus.vertices, torus.faces)


def test_several_components():
    a = trimesh.creation.icosphere(subdivisions=1)
    both = trimesh.util.concatenate([a, a.copy().apply_translation([3, 0, 0])])
    with pytest.raises(ValueError, match="several components \\(2\\)"):
        check_genus0(both.vertices, both.faces)


def test_non_manifold_edge():
    sphere = trimesh.creation.icosphere(subdivisions=1)
    faces = np.concatenate([sphere.faces, sphere.faces[:1]])
    with pytest.raises(ValueError, match="non-manifold edges"):
        check_genus0(sphere.vertices, faces)


def test_non_manifold_vertex():
    # Two tetrahedra sharing vertex 0: every edge has two faces, but vertex 0 has two fans.
    vertices = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], float
    )
    tetrahedron = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    mirrored = np.where(tetrahedron[:, ::-1] == 0, 0, tetrahedron[:, ::-1] + 3)
    with pytest.raises(ValueError, match="1 non-manifold vertices"):
        check_genus0(vertices, np.concatenate([tetrahedron, mirrored]))


def test_inconsistent_orientation():
    sphere = trimesh.creation.icosphere(subdivisions=1)
    faces = sphere.faces.copy()
    faces[0] = faces[0, ::-1]
    with pytest.raises(ValueError, match="consistently oriented"):
        check_genus0(sphere.vertices, faces)


@pytest.mark.parametrize(
    "name, message",
    [
        # cow.off has no boundary as stored; merging its duplicate vertex leaves one edge on four faces.
        ("cow.off", "non-manifold edges|open boundary"),
        ("fertility.off", "genus 4"),
        ("rocker-arm.obj", "genus 1"),
    ],
)
def test_bad_shared_meshes(name, message):
    mesh = _shared(name)
    with pytest.raises(ValueError, match=message):
        check_genus0(mesh.vertices, mesh.faces)


def test_good_shared_mesh():
    mesh = _shared("decimated-knight.off")
    check_genus0(mesh.vertices, mesh.faces)
