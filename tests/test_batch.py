"""``bandelets batch``: a library of small generated files on Dask clusters.

The clusters are real: a LocalCluster of two worker processes, an in-process one for the
reruns, and a scheduler and a worker started here as separate processes on 127.0.0.1.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("distributed")

import bandelets  # noqa: E402
from bandelets.apps.batch import COLUMNS, MANIFEST, batch, collect_inputs  # noqa: E402
from bandelets.apps.cli import main  # noqa: E402
from bandelets.io.files import read_array  # noqa: E402
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

    # Compile (or load) the codec's kernels here first: the workers then load them from numba's
    # cache instead of each compiling them again.
    bandelets.decode(bandelets.encode(crease_normal_map(32), threshold=THRESHOLD, kind="normal-map"))
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
    report = batch([f"{library}/**/*.png"], out, threshold=THRESHOLD, kind="normal-map", workers=2)
    rows = _by_name(report)
    assert list(report.columns) == list(COLUMNS)
    assert sorted(rows) == ["a.png", "b.png", "c.png", "corrupt.png"]
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
    # Two processes shared the work, each reported by its Dask address.
    assert report.worker.str.startswith("tcp://127.0.0.1:").all() and report.worker.nunique() == 2
    on_disk = pd.read_csv(out / "report.csv", keep_default_na=False)
    assert list(on_disk.input) == list(report.input) and list(on_disk.status) == list(report.status)


@pytest.fixture(scope="module")
def threads_client():
    """A Dask cluster inside the test process: one worker thread, no process to start."""
    from distributed import Client, LocalCluster

    with (
        LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster,
        Client(cluster) as client,
    ):
        yield client


def test_images_and_meshes_in_one_run(library, tmp_path, threads_client):
    out = tmp_path / "out"
    options = {"threshold": THRESHOLD, "kind": "normal-map", "bits_per_vertex": 16}
    report = batch([library / "a.png", library / "shapes"], out, **options, client=threads_client)
    image, ball = _by_name(report)["a.png"], _by_name(report)["ball.obj"]
    assert image.status == "ok" and image.kind == "normal-map" and np.isnan(image.bpv)
    assert (
        ball.status == "ok" and ball.kind == "mesh" and np.isnan(ball.bpp) and np.isnan(ball.mean_angle_deg)
    )
    assert ball.output == str(out / "ball.bdl") and ball.bytes == (out / "ball.bdl").stat().st_size
    assert ball.bpv == pytest.approx(8 * ball.bytes / 162) and ball.bpv <= 16  # per vertex of the input
    assert ball.psnr > 30  # the Hausdorff PSNR of the decoded mesh


def _mtimes(out: Path) -> dict[str, int]:
    return {p.name: p.stat().st_mtime_ns for p in out.rglob("*.bdl")}


def test_a_rerun_skips_what_is_done_and_redoes_what_changed(tmp_path, threads_client):
    from bandelets.samples import crease_normal_map

    library, out = tmp_path / "library", tmp_path / "out"
    _png(library / "a.png", crease_normal_map(32))
    _png(library / "b.png", crease_normal_map(40))
    options = {"threshold": THRESHOLD, "kind": "normal-map", "client": threads_client}
    first = bandelets.batch([library], out, **options)  # the package exports the function
    assert list(first.status) == ["ok", "ok"]
    made = _mtimes(out)

    again = batch([library], out, **options)
    assert list(again.status) == ["skipped", "skipped"] and _mtimes(out) == made
    # A skipped file keeps the figures of the run that made it.
    for column in ("bytes", "bpp", "psnr", "mean_angle_deg", "p99_angle_deg"):
        assert list(again[column]) == list(first[column])

    _png(library / "b.png", -crease_normal_map(40))  # new content under the same name
    changed = batch([library], out, **options)
    assert list(changed.status) == ["skipped", "ok"]
    assert _mtimes(out)["a.bdl"] == made["a.bdl"] and _mtimes(out)["b.bdl"] != made["b.bdl"]

    assert list(batch([library], out, **options | {"threshold": 0.1}).status) == ["ok", "ok"]
    assert list(batch([library], out, **options | {"threshold": 0.1}).status) == ["skipped", "skipped"]
    assert list(batch([library], out, **options | {"threshold": 0.1, "force": True}).status) == ["ok", "ok"]
    (out / "a.bdl").write_bytes(b"edited")  # an output changed since: made again
    assert list(batch([library], out, **options | {"threshold": 0.1}).status) == ["ok", "skipped"]
    # One sidecar line per output, however many runs.
    assert len((out / MANIFEST).read_text().splitlines()) == 2


def test_outputs_a_batch_did_not_make_are_kept_and_clashes_fail(tmp_path, threads_client):
    from bandelets.samples import crease_normal_map

    library, out = tmp_path / "library", tmp_path / "out"
    _png(library / "x.png", crease_normal_map(32))
    np.save(library / "x.npy", crease_normal_map(32))  # would also be out/x.bdl
    _png(library / "y.png", crease_normal_map(32))
    out.mkdir()
    (out / "y.bdl").write_bytes(b"someone else's file")
    options = {"threshold": THRESHOLD, "kind": "normal-map", "client": threads_client}
    report = batch([library, tmp_path / "nothing-here.png"], out, **options)
    rows = {Path(i).name: (s, e) for i, s, e in zip(report.input, report.status, report.error, strict=True)}
    assert rows["x.npy"] == ("ok", "")
    assert rows["x.png"] == (
        "failed",
        f"{out / 'x.bdl'}: also the output of {library / 'x.npy'}; rename one of them",
    )
    assert rows["y.png"] == ("failed", f"{out / 'y.bdl'}: already exists (use --force to overwrite)")
    assert rows["nothing-here.png"] == ("failed", f"{tmp_path / 'nothing-here.png'}: no such file")
    assert (out / "y.bdl").read_bytes() == b"someone else's file"
    forced = batch([library / "y.png"], out, **options | {"force": True})
    assert list(forced.status) == ["ok"] and bandelets.decode((out / "y.bdl").read_bytes()).shape == (
        32,
        32,
        3,
    )


def test_inputs_are_files_folders_and_globs(library):
    files, missing = collect_inputs(
        [library / "a.png", library, f"{library}/**/c.png", f"{library}/*.txt", library / "nope.png"]
    )
    relative = {str(path.relative_to(library)): str(rel) for path, rel in files}
    assert relative == {
        "a.png": "a.png",  # a file: its name; the folder's a.png is the same file, dropped
        "b.png": "b.png",
        "maps/c.png": "maps/c.png",  # under the folder, and under the glob's fixed part
        "maps/corrupt.png": "maps/corrupt.png",
        "shapes/ball.obj": "shapes/ball.obj",
    }
    assert missing == [f"{library}/*.txt", str(library / "nope.png")]


def test_bad_arguments_fail_before_any_work(tmp_path, library, capsys):
    with pytest.raises(ValueError, match="report must be a .csv or .parquet"):
        batch([library], tmp_path / "out", report=tmp_path / "report.txt")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no images or meshes"):
        batch([tmp_path / "empty"], tmp_path / "out")
    with pytest.raises(ValueError, match="bpp must be a positive number"):
        batch([library], tmp_path / "out", bpp=-1)
    assert main(["batch", str(library), "--out", str(tmp_path), "--bpp", "1", "--psnr", "40"]) == 2
    assert "not allowed with argument" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_parquet_report(tmp_path, library, threads_client):
    pytest.importorskip("pyarrow")
    report = tmp_path / "report.parquet"
    options = {"threshold": THRESHOLD, "kind": "normal-map", "client": threads_client}
    frame = batch(
        [library / "a.png", library / "maps" / "corrupt.png"], tmp_path / "out", report=report, **options
    )
    on_disk = pd.read_parquet(report)
    assert list(on_disk.columns) == list(COLUMNS) and list(on_disk.status) == ["ok", "failed"]
    assert on_disk.bytes[0] == frame.bytes[0] == (tmp_path / "out" / "a.bdl").stat().st_size


def test_parquet_needs_pyarrow(tmp_path, library, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "pyarrow" else real(name, *a)
    )
    with pytest.raises(ValueError, match=r"needs pyarrow \(pip install pyarrow\)"):
        batch([library], tmp_path / "out", report=tmp_path / "report.parquet")


def test_the_command_line_loads_dask_only_for_batch():
    code = (
        "import sys\nfrom bandelets.apps.cli import main\n"
        "try:\n    main(['batch', '--help'])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in ('dask', 'distributed', 'pandas') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "--scheduler ADDRESS" in done.stdout and done.stdout.rstrip().endswith("[]")


def _start(args: list[str], log: Path) -> subprocess.Popen:
    """A Dask process (``python -m distributed.cli.NAME ...``) importing this bandelets."""
    source = str(Path(bandelets.__file__).resolve().parents[1])
    env = os.environ | {"PYTHONPATH": os.pathsep.join(filter(None, [source, os.environ.get("PYTHONPATH")]))}
    return subprocess.Popen(
        [sys.executable, "-m", *args], env=env, stdout=log.open("w"), stderr=subprocess.STDOUT
    )


def test_the_command_line_on_a_scheduler_and_worker_started_here(library, tmp_path, capsys):
    from distributed import Client

    scheduler_file, out = tmp_path / "scheduler.json", tmp_path / "out"
    loopback = ["--host", "127.0.0.1", "--no-dashboard"]
    processes = [
        _start(
            [
                "distributed.cli.dask_scheduler",
                *loopback,
                "--port",
                "0",
                "--scheduler-file",
                str(scheduler_file),
            ],
            tmp_path / "scheduler.log",
        )
    ]
    try:
        worker_args = ["--scheduler-file", str(scheduler_file), "--nthreads", "1", "--no-nanny"]
        processes.append(
            _start(["distributed.cli.dask_worker", *loopback, *worker_args], tmp_path / "worker.log")
        )
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        with Client(scheduler_file=str(scheduler_file), timeout=60) as client:
            client.wait_for_workers(1, timeout=60)
            address, [worker] = client.scheduler.address, list(client.scheduler_info()["workers"])
        assert address.startswith("tcp://127.0.0.1:") and worker.startswith("tcp://127.0.0.1:")
        argv = ["batch", str(library / "a.png"), f"{library}/maps/*.png", "--out", str(out)]
        status = main([*argv, "--kind", "normal-map", "--threshold", str(THRESHOLD), "--scheduler", address])
    finally:
        for process in reversed(processes):
            process.terminate()
            process.wait(timeout=30)
    assert status == 1  # the corrupt PNG
    captured = capsys.readouterr()
    assert f"bandelets: failed: {library / 'maps' / 'corrupt.png'}: not a readable PNG" in captured.err
    assert captured.out.strip() == "2 ok, 0 skipped, 1 failed"
    report = pd.read_csv(out / "report.csv", keep_default_na=False)
    assert list(report.status) == ["ok", "ok", "failed"] and set(report.worker) == {worker}
    assert (out / "a.bdl").is_file() and (out / "c.bdl").is_file()
