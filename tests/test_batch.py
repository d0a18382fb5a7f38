"""``bandelets batch``: a library of small generated files on Dask clusters.

The clusters are real: a LocalCluster of two worker processes, an in-process one for the
reruns, and a scheduler and a worker started here as separate processes on 127.0.0.1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("distributed")

import bandelets  # noqa: E402
from bandelets.batch import COLUMNS, batch  # noqa: E402
from bandelets.files import read_array  # noqa: E402
from bandelets.metrics import psnr  # noqa: E402

THRESHOLD = 0.05
#: The normal maps of the library and their sides.
MAPS = {"a.png": 32, "b.png": 48, "maps/c.png": 64}


def _png(path: Path, normals: np.ndarray) -> None:
    import imagecodecs

    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(imagecodecs.png_encode(np.uint16(np.rint((normals + 1) / 2 * 65535))))


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> Path:
    """Three normal maps (one in a subfolder), a corrupt PNG and a small closed mesh."""
    import trimesh

    from bandelets.samples import crease_normal_map

    root = tmp_path_factory.mktemp("library")
    for name, size in MAPS.items():
        _png(root / name, crease_normal_map(size))
    (root / "maps" / "corrupt.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 40)
    (root / "shapes").mkdir()
    trimesh.creation.icosphere(subdivisions=2).export(root / "shapes" / "ball.obj")
    return root


def _by_name(report: pd.DataFrame) -> dict[str, pd.Series]:
    return {Path(row.input).name: row for _, row in report.iterrows()}


def test_local_cluster_of_two_processes(library, tmp_path):
    out = tmp_path / "out"
    report = batch([library], out, threshold=THRESHOLD, kind="normal-map", bits_per_vertex=16, workers=2)
    rows = _by_name(report)
    assert list(report.columns) == list(COLUMNS)
    assert sorted(rows) == ["a.png", "b.png", "ball.obj", "c.png", "corrupt.png"]
    # The corrupt file failed with the error `bandelets encode` prints; the rest went on.
    assert rows["corrupt.png"].status == "failed"
    assert rows["corrupt.png"].error.startswith(f"{library / 'maps' / 'corrupt.png'}: not a readable PNG")
    assert not (out / "maps" / "corrupt.bdl").exists()
    for relative, size in MAPS.items():
        row, path = rows[Path(relative).name], out / Path(relative).with_suffix(".bdl")
        assert row.status == "ok" and row.output == str(path) and row.error == ""
        data = path.read_bytes()  # every figure of the report is the file's
        assert row.bytes == len(data) and row.bpp == pytest.approx(8 * len(data) / size**2)
        source, _ = read_array(library / relative, "normal-map")
        assert row.psnr == pytest.approx(psnr(source, bandelets.decode(data), "normal-map"))
        assert 0 < row.mean_angle_deg < row.p99_angle_deg < 90
    ball = rows["ball.obj"]
    assert ball.status == "ok" and ball.kind == "mesh" and np.isnan(ball.bpp)
    assert ball.bytes == (out / "shapes" / "ball.bdl").stat().st_size
    assert ball.bpv == pytest.approx(8 * ball.bytes / 162) and ball.bpv <= 16 and ball.psnr > 20
    # Two processes shared the work, each reported by its Dask address.
    assert report.worker.str.startswith("tcp://127.0.0.1:").all() and report.worker.nunique() == 2
    on_disk = pd.read_csv(out / "report.csv", keep_default_na=False)
    assert list(on_disk.input) == list(report.input) and list(on_disk.status) == list(report.status)
