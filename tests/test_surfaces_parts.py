"""Meshes of several parts with closed genus-0 components: each such part on the spherical path,
the rest on the chart route, in one record (:mod:`bandelets.surfaces.parts`)."""

from __future__ import annotations

import json

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("DracoPy")
pytest.importorskip("pymeshlab")

from bandelets.apps.cli import main  # noqa: E402
from bandelets.surfaces import chartcodec, codec, metrics, parts  # noqa: E402
from bandelets.surfaces.codec import decode_mesh, encode_mesh  # noqa: E402


def _bumpy(subdivisions: int, shift: float):
    mesh = trimesh.creation.icosphere(subdivisions)
    d = mesh.vertices
    mesh.vertices = d * (1.0 + 0.15 * np.sin(4 * d[:, 0]) * np.cos(3 * d[:, 2]))[:, None] + (shift, 0, 0)
    return mesh


def _sphere_and_cut():
    """A closed bumpy sphere (2,562 vertices) and, beside it, a sphere cut open (one boundary loop)."""
    cut = trimesh.creation.icosphere(2).apply_translation([3.0, 0, 0])
    cut = trimesh.Trimesh(cut.vertices, cut.faces[cut.triangles_center[:, 2] < 0.5])
    cut.remove_unreferenced_vertices()
    return trimesh.util.concatenate([_bumpy(4, 0.0), cut])


def test_split_keeps_closed_genus0_parts_alone_and_the_rest_together():
    tiny = trimesh.creation.icosphere(0).apply_translation([0, 5.0, 0])  # 12 vertices: too few
    mesh = trimesh.util.concatenate([_sphere_and_cut(), tiny])
    found = parts.split(mesh.vertices, mesh.faces)
    assert [len(p.vertices) for p in found] == [2562, len(mesh.vertices) - 2562]
    assert metrics.topology(found[1])[1:] == (2, 1)  # the cut sphere and the tiny one, together
    assert parts.split(*_open(mesh)) is None  # nothing closed of genus 0


def _open(mesh):
    faces = mesh.faces[mesh.triangles_center[:, 2] < 0.5]
    used, compact = np.unique(faces, return_inverse=True)
    return mesh.vertices[used], compact.reshape(-1, 3)


def test_two_closed_parts_beat_one_chart_image():
    both = trimesh.util.concatenate([_bumpy(3, 0.0), _bumpy(3, 3.0)])
    n_bytes = 2 * len(both.vertices) // 8  # 2 bits per vertex
    data = encode_mesh(both, n_bytes=n_bytes)
    assert parts.is_parts_file(data) and len(data) <= n_bytes
    decoded = decode_mesh(data)
    assert metrics.topology(decoded) == (len(both.vertices), 2, 0)
    charted = chartcodec.decode_charts(chartcodec.encode_charts(both, 8 * n_bytes))
    ours = metrics.hausdorff_psnr(both, decoded, samples=50_000)
    assert ours > metrics.hausdorff_psnr(both, charted, samples=50_000) + 3.0


def test_the_chart_route_is_coded_only_beside_a_rest_or_at_high_rates(monkeypatch):
    """Every component closed of genus 0, at a low rate: the record alone (no chart image coded to
    compare); at a high rate, or beside an open part: the chart route's file is coded too."""
    coded = []
    chart = chartcodec.encode_charts
    monkeypatch.setattr(
        chartcodec, "encode_charts", lambda mesh, *a, **k: coded.append(mesh) or chart(mesh, *a, **k)
    )
    both = trimesh.util.concatenate([_bumpy(3, 0.0), _bumpy(3, 3.0)])
    assert parts.is_parts_file(encode_mesh(both, bits_per_vertex=2)) and coded == []
    encode_mesh(both, bits_per_vertex=codec.RECORD_ALONE_BELOW)
    assert [len(m.vertices) for m in coded] == [len(both.vertices)]
    coded.clear()
    mesh = _sphere_and_cut()
    encode_mesh(mesh, bits_per_vertex=4)
    assert sorted(len(m.vertices) for m in coded) == [len(mesh.vertices) - 2562, len(mesh.vertices)]


def test_two_closed_parts_through_the_command_line(tmp_path, capsys):
    mesh = trimesh.util.concatenate([_bumpy(3, 0.0), _bumpy(3, 3.0)])
    source, bdl, out = tmp_path / "in.ply", tmp_path / "m.bdl", tmp_path / "out.ply"
    mesh.export(source)
    assert main(["mesh-encode", str(source), str(bdl), "--bits-per-vertex", "2"]) == 0
    summary = capsys.readouterr().err.strip()
    assert main(["info", str(bdl)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["representation"] == "parts" and "2 parts: spherical geometry image" in summary
    assert [p["representation"] for p in info["parts"]] == ["spherical geometry image"] * 2
    assert info["vertices"] == len(mesh.vertices)
    assert main(["mesh-decode", str(bdl), str(out)]) == 0
    decoded = trimesh.load(out, force="mesh", process=False)
    assert metrics.topology(decoded) == (len(mesh.vertices), 2, 0)
    assert metrics.hausdorff_psnr(mesh, decoded, samples=20_000) > 45


def test_a_record_with_a_rest_keeps_every_component_and_boundary():
    """A closed part beside an open one: the record of parts (kept or not by the encoder) decodes
    to both, the open one with its boundary loop and its faces."""
    mesh = _sphere_and_cut()
    found = parts.split(mesh.vertices, mesh.faces)
    fixed = [0, chartcodec.faces_bytes(found[1]) * 9 // 8 + 48]
    record = parts.encode_parts(found, 8 * 2000, lambda part, n: encode_mesh(part, n_bytes=n), fixed)
    assert len(record) <= 2000 and [f[:4] == chartcodec.MAGIC for f in parts.files(record)] == [False, True]
    decoded = decode_mesh(record)
    assert metrics.topology(decoded) == (len(mesh.vertices), 2, 1)
    assert metrics.hausdorff_psnr(mesh, decoded, samples=20_000) > 50


def test_a_damaged_record_of_parts_is_refused_in_one_line():
    both = trimesh.util.concatenate([_bumpy(3, 0.0), _bumpy(3, 3.0)])
    data = encode_mesh(both, n_bytes=400)
    assert parts.is_parts_file(data)
    damaged = bytearray(data)
    damaged[len(data) // 2] ^= 0x10
    for bad, message in ((bytes(damaged), "CRC mismatch"), (data[:-9], "CRC mismatch|truncated")):
        with pytest.raises(ValueError, match=message):
            decode_mesh(bad)
    nested = parts.encode_parts([both], 8 * (len(data) + 20), lambda part, n: data)
    with pytest.raises(ValueError, match="inside one"):
        decode_mesh(nested)


@pytest.mark.parametrize(
    "edit, message",
    [
        (
            lambda v, f: (np.where(np.arange(len(v))[:, None] == 200, np.nan, v), f),
            "vertex 200 has a non-finite",
        ),
        (lambda v, f: (v, np.vstack([f, [[0, 0, 1]]])), "1 face repeats a vertex"),
        (lambda v, f: (np.vstack([v, (v[0] + v[1]) / 2]), np.vstack([f, [[0, 1, len(v)]]])), "of zero area"),
        (lambda v, f: (v, f[:0]), "no triangles"),
    ],
)
def test_bad_meshes_of_two_parts_get_one_line(edit, message):
    both = trimesh.util.concatenate([_bumpy(2, 0.0), _bumpy(2, 3.0)])
    vertices, faces = edit(np.asarray(both.vertices), np.asarray(both.faces))
    with pytest.raises(ValueError, match=message) as error:
        encode_mesh(trimesh.Trimesh(vertices, faces, process=False), bits_per_vertex=8)
    assert "\n" not in str(error.value)
