"""The multi-chart route of the mesh codec: open, higher-genus and several-part meshes."""

from __future__ import annotations

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("DracoPy")
pytest.importorskip("pymeshlab")

from bandelets.format.varint import varint  # noqa: E402
from bandelets.surfaces import chartcodec, charts, codec, metrics  # noqa: E402


def _round_trip(mesh, bits_per_vertex: float):
    data = codec.encode_mesh(mesh, bits_per_vertex=bits_per_vertex)
    assert chartcodec.is_chart_file(data)
    assert len(data) <= bits_per_vertex * len(mesh.vertices) / 8
    return codec.decode_mesh(data)


def test_torus_round_trip():
    torus = trimesh.creation.torus(1.0, 0.35, major_sections=48, minor_sections=16)
    decoded = _round_trip(torus, 12)
    assert len(decoded.faces) == len(torus.faces) and len(decoded.vertices) == len(torus.vertices)
    assert metrics.topology(decoded)[1:] == (1, 0)
    euler = len(decoded.vertices) - len(decoded.edges_unique) + len(decoded.faces)
    assert euler == 0  # still a torus
    assert metrics.hausdorff_psnr(torus, decoded, samples=20_000) > 45


def test_cut_sphere_keeps_its_boundary_loop():
    sphere = trimesh.creation.icosphere(3)
    keep = ~np.any(sphere.vertices[sphere.faces][:, :, 2] > 0.5, axis=1)
    cut = trimesh.Trimesh(sphere.vertices, sphere.faces[keep])
    cut.remove_unreferenced_vertices()
    decoded = _round_trip(cut, 16)
    assert metrics.topology(cut)[1:] == (1, 1)
    assert metrics.topology(decoded)[1:] == (1, 1)
    assert metrics.hausdorff_psnr(cut, decoded, samples=20_000) > 45


def test_two_components_kept():
    first = trimesh.creation.icosphere(3)
    second = trimesh.creation.icosphere(3).apply_translation([3.0, 0, 0])
    both = trimesh.util.concatenate([first, second])
    decoded = _round_trip(both, 16)
    assert metrics.topology(decoded)[1:] == (2, 0)
    # Each part comes back in its place: both halves of the decoded box hold one sphere.
    centres = decoded.vertices[:, 0]
    assert np.sum(centres > 1.5) == np.sum(centres < 1.5) == len(first.vertices)
    assert metrics.hausdorff_psnr(both, decoded, samples=20_000) > 45


def test_closed_genus0_mesh_stays_spherical():
    data = codec.encode_mesh(trimesh.creation.icosphere(2), bpp=2.0, size=32)
    assert not chartcodec.is_chart_file(data)


def _square_grid(n: int = 4):
    """An open n x n grid of squares, two triangles each."""
    ij = np.arange(n + 1)
    x, y = np.meshgrid(ij, ij, indexing="ij")
    vertices = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)]).astype(float)
    index = lambda i, j: i * (n + 1) + j  # noqa: E731
    faces = []
    for i in range(n):
        for j in range(n):
            faces += [
                [index(i, j), index(i + 1, j), index(i + 1, j + 1)],
                [index(i, j), index(i + 1, j + 1), index(i, j + 1)],
            ]
    return vertices, np.array(faces)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda v, f: (v, f[:0]), "no triangles"),
        (lambda v, f: (np.where(np.arange(len(v))[:, None] == 3, np.nan, v), f), "vertex 3 has a non-finite"),
        (lambda v, f: (v, f[:1]), "single triangle"),
        (lambda v, f: (v, np.vstack([f, [[0, 0, 1]]])), "repeats a vertex"),
        (lambda v, f: (np.vstack([v, [[0, 0.5, 0]]]), np.vstack([f, [[0, 1, len(v)]]])), "zero area"),
    ],
)
def test_bad_meshes_refused_with_one_line(edit, message):
    vertices, faces = edit(*_square_grid())
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    with pytest.raises(ValueError, match=message) as error:
        codec.encode_mesh(mesh, bits_per_vertex=16)
    assert "\n" not in str(error.value)


def test_every_chart_is_a_disk_and_the_layout_is_inside_the_image():
    torus = trimesh.creation.torus(1.0, 0.35, major_sections=48, minor_sections=16)
    faces = np.asarray(torus.faces)
    labels = charts.region_charts(faces, faces_per_chart=200)
    for chart in range(labels.max() + 1):
        assert charts.boundary_loop(faces[labels == chart]) is not None
    layout = charts.layout(faces, labels, 64)
    assert layout.pixels.min() >= 0 and layout.pixels.max() <= 63
    assert np.array_equal(
        np.unique(layout.corner_vertex[charts.owners(layout)]), np.arange(len(torus.vertices))
    )


def test_corrupt_chart_file_refused():
    torus = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12)
    data = bytearray(codec.encode_mesh(torus, bits_per_vertex=16))
    data[len(data) // 2] ^= 0xFF
    with pytest.raises(ValueError, match="corrupt"):
        codec.decode_mesh(bytes(data))


def test_draco_only_record_decodes_to_dracos_mesh():
    import zlib

    from bandelets.surfaces import draco

    torus = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12)
    stream = draco.encode(torus, 2000)
    body = chartcodec.MAGIC + bytes([chartcodec.RECORD_VERSION, chartcodec.DRACO_ONLY])
    body += varint(len(stream)) + stream
    decoded = codec.decode_mesh(body + zlib.crc32(body).to_bytes(4, "little"))
    expected = draco.decode(stream)
    assert np.array_equal(decoded.faces, expected.faces)
    assert np.allclose(decoded.vertices, expected.vertices)
    with pytest.raises(ValueError, match="bytes after the Draco stream"):
        body += b"\0"
        codec.decode_mesh(body + zlib.crc32(body).to_bytes(4, "little"))


def test_normal_layer_round_trip():
    from bandelets.surfaces import normallayer

    offsets = np.random.default_rng(1).laplace(scale=0.01, size=5000)
    step, data = normallayer.encode(offsets, 8 * 2000, scale=1.0)
    assert len(data) <= 2000 and step > 0
    q = normallayer.decode(data, len(offsets))
    assert np.all(np.abs(q * step - offsets) <= step / 2 + 1e-12)  # each offset to its nearest step
    assert normallayer.encode(offsets, 8, scale=1.0) is None  # one byte holds no 5000 offsets


def test_a_rough_scan_takes_the_normal_layer():
    """Detail at the scale of the vertices (a noisy cut sphere): the image at part of the bits and
    each vertex's offset along its normal in the rest beat the image alone by far."""
    sphere = trimesh.creation.icosphere(4)
    noise = 1 + 0.01 * np.random.default_rng(0).standard_normal((len(sphere.vertices), 1))
    cut = trimesh.Trimesh(sphere.vertices * noise, sphere.faces[sphere.triangles_center[:, 2] < 0.5])
    cut.remove_unreferenced_vertices()
    bits = 8 * len(cut.vertices)
    layered = chartcodec.encode_charts(cut, bits, fallback=False)
    plain = chartcodec.encode_charts(cut, bits, fallback=False, layer=False)
    assert chartcodec.describe(layered)["normal_layer_bytes"] > 0 and len(layered) <= bits / 8
    assert chartcodec.describe(plain)["normal_layer_bytes"] == 0
    from bandelets.apps.meshsummary import mesh_encode_summary

    line = mesh_encode_summary("in.obj", "out.bdl", cut, layered, 1.0)
    assert f"and a normal layer of {chartcodec.describe(layered)['normal_layer_bytes']} bytes" in line
    decoded = codec.decode_mesh(layered)
    assert np.array_equal(decoded.faces, codec.decode_mesh(plain).faces)
    psnr = [metrics.hausdorff_psnr(cut, m, samples=20_000) for m in (decoded, codec.decode_mesh(plain))]
    assert psnr[0] > psnr[1] + 4, psnr
