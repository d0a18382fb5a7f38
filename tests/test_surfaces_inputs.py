"""Every mesh a user has, through the command line: STL and glTF input, non-manifold meshes split
into manifold pieces, and bad meshes refused with one line and no output file."""

from __future__ import annotations

import json

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("DracoPy")
pytest.importorskip("pymeshlab")

from bandelets.apps.cli import main  # noqa: E402
from bandelets.surfaces import chartcodec, metrics, repair  # noqa: E402


def _round_trip(tmp_path, capsys, mesh, suffix: str, bits_per_vertex: float):
    """``mesh`` written as ``suffix``, then mesh-encode, info and mesh-decode: the decoded mesh,
    the summary line and the info."""
    source, bdl, out = tmp_path / f"in{suffix}", tmp_path / "m.bdl", tmp_path / "out.obj"
    mesh.export(source)
    capsys.readouterr()
    assert main(["mesh-encode", str(source), str(bdl), "--bits-per-vertex", str(bits_per_vertex)]) == 0
    summary = capsys.readouterr().err.strip().splitlines()
    assert len(summary) == 1 and summary[0].startswith(f"{source} -> {bdl}: ")
    assert bdl.stat().st_size <= bits_per_vertex * len(mesh.vertices) / 8
    assert main(["info", str(bdl)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert main(["mesh-decode", str(bdl), str(out)]) == 0
    return trimesh.load(out, force="mesh", process=False), summary[0], info


def _cut_sphere():
    sphere = trimesh.creation.icosphere(3)
    cut = trimesh.Trimesh(sphere.vertices, sphere.faces[sphere.triangles_center[:, 2] < 0.5])
    cut.remove_unreferenced_vertices()
    return cut


def test_stl_round_trip_of_an_open_mesh(tmp_path, capsys):
    """STL stores a triangle soup: the load welds it back into a surface of one boundary loop."""
    cut = _cut_sphere()
    decoded, summary, info = _round_trip(tmp_path, capsys, cut, ".stl", 16)
    assert info["representation"] in ("multi-chart geometry image", "draco")
    assert f"{len(cut.vertices)} vertices" in summary
    assert len(decoded.faces) == len(cut.faces)
    assert metrics.topology(decoded) == (len(cut.vertices), 1, 1)
    assert metrics.hausdorff_psnr(cut, decoded, samples=20_000) > 45


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_gltf_round_trip_of_two_parts(tmp_path, capsys, suffix):
    first = trimesh.creation.icosphere(2)
    both = trimesh.util.concatenate([first, trimesh.creation.icosphere(2).apply_translation([3.0, 0, 0])])
    decoded, _, info = _round_trip(tmp_path, capsys, both, suffix, 24)
    assert info["vertices"] == len(both.vertices) and info["faces"] == len(both.faces)
    assert metrics.topology(decoded) == (len(both.vertices), 2, 0)
    assert metrics.hausdorff_psnr(both, decoded, samples=20_000) > 45


def test_glb_of_a_closed_genus0_mesh_takes_the_spherical_path(tmp_path, capsys):
    sphere = trimesh.creation.icosphere(3)
    decoded, summary, info = _round_trip(tmp_path, capsys, sphere, ".glb", 8)
    assert info["representation"] == "spherical geometry image" and "spherical geometry image" in summary
    assert len(decoded.vertices) == len(sphere.vertices)
    assert metrics.hausdorff_psnr(sphere, decoded, samples=20_000) > 50


def _grid(n: int = 6):
    """An open n x n grid of squares in the plane z = 0, two triangles each."""
    ij = np.arange(n + 1)
    x, y = np.meshgrid(ij, ij, indexing="ij")
    vertices = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)]).astype(float)
    quads = (ij[:-1, None] * (n + 1) + ij[None, :-1]).ravel()
    faces = np.concatenate(
        [
            np.column_stack([quads, quads + n + 1, quads + n + 2]),
            np.column_stack([quads, quads + n + 2, quads + 1]),
        ]
    )
    return vertices, faces


def test_manifold_pieces_free_a_fin_and_a_pinched_vertex():
    vertices, faces = _grid()
    # A fin on the interior edge 8-16 (three faces on it), and a cone pinched at vertex 48 (the
    # grid's far corner): two fans of faces round one vertex.
    fin = len(vertices)
    vertices = np.vstack([vertices, [[1.5, 1.5, 1.0]], [[7, 7, 1], [8, 6, 1], [6, 8, 1]]])
    faces = np.vstack([faces, [[8, 16, fin]], [[48, fin + 1, fin + 2], [48, fin + 2, fin + 3]]])
    assert (
        np.max(
            np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), 1), axis=0, return_counts=True)[1]
        )
        == 3
    )
    split_vertices, split_faces, split = repair.manifold_pieces(vertices, faces)
    assert (split.edges, split.first_edge) == (1, (8, 16))
    assert split.vertices == 3 and split.copies == len(split_vertices) - len(vertices) >= 3
    assert "split into manifold pieces: 1 non-manifold edge (first: vertices 8-16)" in split.summary()
    # The same faces on copies of the same positions; every edge now on two faces at most.
    assert np.array_equal(split_vertices[split_faces], vertices[faces])
    assert (
        np.max(
            np.unique(
                np.sort(split_faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), 1), axis=0, return_counts=True
            )[1]
        )
        == 2
    )
    assert not repair.manifold_pieces(*_grid())[2]  # a manifold mesh is left as it is


def test_a_non_manifold_mesh_is_coded_in_manifold_pieces(tmp_path, capsys):
    sphere = trimesh.creation.icosphere(2)
    other = trimesh.creation.icosphere(2).apply_translation([2.0, 0, 0])
    # The two spheres share a vertex (at x = 1) and a fin of one triangle on an edge of the first.
    touching = int(np.argmin(other.vertices[:, 0]))
    faces = np.vstack([sphere.faces, np.asarray(other.faces) + len(sphere.vertices)])
    faces[faces == len(sphere.vertices) + touching] = int(np.argmax(sphere.vertices[:, 0]))
    edge = sphere.faces[0, :2]
    vertices = np.vstack([sphere.vertices, other.vertices, [[0, 0, 2.0]]])
    faces = np.vstack([faces, [[edge[1], edge[0], len(vertices) - 1]]])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.remove_unreferenced_vertices()
    source, bdl, out = tmp_path / "pinched.ply", tmp_path / "p.bdl", tmp_path / "p.obj"
    source.write_bytes(mesh.export(file_type="ply"))
    assert main(["mesh-encode", str(source), str(bdl), "--bits-per-vertex", "24"]) == 0
    summary = capsys.readouterr().err
    assert "split into manifold pieces: 1 non-manifold edge" in summary and "\n" not in summary.strip()
    assert main(["mesh-decode", str(bdl), str(out)]) == 0
    decoded = trimesh.load(out, force="mesh", process=False)
    assert len(decoded.faces) == len(mesh.faces) and len(decoded.vertices) > len(mesh.vertices)
    assert metrics.hausdorff_psnr(mesh, decoded, samples=20_000) > 40


def _obj(path, vertices, faces) -> None:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(vertices, float).tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(faces).tolist()]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda v, f: (v, f[:0]), "no triangles found"),
        (lambda v, f: (np.where(np.arange(len(v))[:, None] == 3, np.nan, v), f), "vertex 3 has a non-finite"),
        (lambda v, f: (v, f[:1]), "single triangle"),
        (lambda v, f: (v, np.vstack([f, [[0, 0, 1]]])), "1 face repeats a vertex"),
        (
            lambda v, f: (np.vstack([v, [[0, 0.5, 0]]]), np.vstack([f, [[0, 1, len(v)]]])),
            "1 face of zero area",
        ),
    ],
)
def test_bad_meshes_get_one_line_through_the_command_line(tmp_path, capsys, edit, message):
    path, bdl = tmp_path / "bad.obj", tmp_path / "bad.bdl"
    _obj(path, *edit(*_grid(4)))
    assert main(["mesh-encode", str(path), str(bdl), "--bits-per-vertex", "64"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"bandelets: error: {path}: ") and message in err, err
    assert "\n" not in err and "Traceback" not in err
    assert not bdl.exists() and list(tmp_path.iterdir()) == [path]  # no partial output, no temporary


def test_a_non_orientable_mesh_is_refused_with_one_line():
    """A Moebius strip: no split makes its faces consistently oriented."""
    n = 24
    angle = np.arange(n) * 2 * np.pi / n
    rows = []
    for side in (-0.3, 0.3):
        radius = 1 + side * np.cos(angle / 2)
        rows.append(
            np.column_stack([radius * np.cos(angle), radius * np.sin(angle), side * np.sin(angle / 2)])
        )
    vertices = np.vstack(rows)
    k = np.arange(n)
    nxt, top = (k + 1) % n, k + n
    top_next = np.where(k + 1 < n, nxt + n, nxt)  # the strip's half twist: the edge joins the other side
    bottom_next = np.where(k + 1 < n, nxt, nxt + n)
    faces = np.vstack([np.column_stack([k, bottom_next, top_next]), np.column_stack([k, top_next, top])])
    with pytest.raises(ValueError, match="non-orientable") as error:
        chartcodec.encode_charts(trimesh.Trimesh(vertices, faces, process=False), 8 * 4000)
    assert "\n" not in str(error.value)
