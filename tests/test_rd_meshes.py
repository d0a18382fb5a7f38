"""``bandelets rd`` on meshes: bandelets and wavelets on geometry images against Draco."""

from __future__ import annotations

import csv
import sys
from functools import partial

import imagecodecs
import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("pymeshlab")

from bandelets.apps import rd  # noqa: E402
from bandelets.apps.cli import main  # noqa: E402


def _run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture
def sphere_file(tmp_path):
    path = tmp_path / "ico.obj"
    path.write_text(trimesh.creation.icosphere(subdivisions=2).export(file_type="obj"))
    return path


def test_rd_on_a_mesh_with_draco_writes_csv_png_and_real_bytes(tmp_path, capsys, sphere_file, monkeypatch):
    pytest.importorskip("DracoPy", reason="DracoPy is not installed: pip install DracoPy")
    from bandelets.surfaces import metrics

    # Fewer Hausdorff samples than a real run takes, to keep the test quick.
    monkeypatch.setattr(metrics, "hausdorff_psnr", partial(metrics.hausdorff_psnr, samples=20_000))
    out = tmp_path / "out"
    status, printed, err = _run(capsys, "rd", sphere_file, "--size", 32, "--rates", "12,24", "--out", out)
    assert status == 0, err
    with open(out / "rd.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == [
        "input",
        "codec",
        "target",
        "bytes",
        "bpv",
        "psnr",
        "encode_s",
        "decode_s",
        "side",
    ]
    assert [r["side"] for r in rows] == ["32"] * 4 + [""] * 2
    assert [(r["codec"], float(r["target"])) for r in rows] == [
        (c, t) for c in ("bandelet", "wavelet", "draco") for t in (12.0, 24.0)
    ]
    vertices = len(trimesh.creation.icosphere(subdivisions=2).vertices)
    for row in rows:
        extension = "drc" if row["codec"] == "draco" else "bdl"
        written = (out / "ico" / f"{row['codec']}-{float(row['target']):g}bpv.{extension}").stat().st_size
        assert int(row["bytes"]) == written
        assert float(row["bpv"]) == pytest.approx(8 * written / vertices, rel=1e-5)
        assert float(row["bpv"]) <= float(row["target"])
        assert 15 < float(row["psnr"]) < 120
    draco = [float(r["psnr"]) for r in rows if r["codec"] == "draco"]
    assert draco[1] > draco[0]  # more bytes, more bits per coordinate
    assert imagecodecs.png_decode((out / "rd.png").read_bytes()).ndim == 3
    assert "draco: DracoPy " in printed and "Draco bitstream" in printed and "bpv range" in printed
    assert "geometry images against the original before coding: 32 x 32: " in printed


def test_draco_file_decodes_to_the_mesh_it_wrote(sphere_file):
    pytest.importorskip("DracoPy", reason="DracoPy is not installed: pip install DracoPy")
    from bandelets.surfaces import draco

    mesh = trimesh.load(sphere_file, force="mesh")
    small, large = draco.encode(mesh, 300), draco.encode(mesh, 3000)
    assert len(small) <= 300 < len(large) <= 3000
    decoded = draco.decode(large)
    assert decoded.faces.shape == mesh.faces.shape
    # Quantized on a grid over the bounding box: every vertex moves by less than a step.
    assert np.abs(np.sort(decoded.vertices, axis=0) - np.sort(mesh.vertices, axis=0)).max() < 0.05
    with pytest.raises(ValueError, match="cannot fit"):
        draco.encode(mesh, 10)
    with pytest.raises(ValueError, match="not a Draco mesh file"):
        draco.decode(b"DRACO but not really")


def test_draco_without_dracopy_is_one_clear_error(tmp_path, capsys, sphere_file, monkeypatch):
    monkeypatch.setitem(sys.modules, "DracoPy", None)  # makes ``import DracoPy`` fail
    status, _, err = _run(capsys, "rd", sphere_file, "--codecs", "draco", "--out", tmp_path / "out")
    assert status == 2
    assert err.strip() == "bandelets: error: the draco codec needs DracoPy (pip install DracoPy)"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--codecs", "jpeg2000"], "unknown codec 'jpeg2000' for meshes"),
        (["sample:crease@32"], "give either images or meshes, not both"),
        (["--size", "7"], "geometry image size must be even"),
    ],
)
def test_mesh_rd_errors(tmp_path, capsys, sphere_file, extra, message):
    status, _, err = _run(capsys, "rd", sphere_file, *extra, "--out", tmp_path / "out")
    assert status == 2 and message in err and "Traceback" not in err


def test_run_refuses_images_and_meshes_together(sphere_file, tmp_path):
    mesh_source = rd.load(str(sphere_file), size=16)
    assert isinstance(mesh_source, rd.MeshSource) and mesh_source.image(16).shape == (16, 16, 3)
    with pytest.raises(ValueError, match="not both"):
        rd.run([mesh_source, rd.load("sample:crease@32")], [1.0], ["bandelet"], tmp_path)
