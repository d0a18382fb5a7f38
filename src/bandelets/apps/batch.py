"""``bandelets batch``: compress a whole library of images and meshes on Dask.

The work of one file is :func:`compress_file`, a plain function of a :class:`Job` that reads
the input, encodes it (:func:`bandelets.encode`, or :func:`bandelets.surfaces.codec.encode_mesh`
for a mesh), writes the .bdl file atomically, decodes it and measures it. :func:`batch` submits
one call per file to a ``dask.distributed`` cluster, largest files first: by default a
``LocalCluster`` of processes on this machine, or an existing cluster given by its scheduler's
address. Dask is the Python ecosystem's engine for this and runs the same function on a
laptop and on a cluster, so nothing here schedules, retries or balances by hand; the workers
must see the inputs and the output folder at the same paths as the client (one machine, or a
shared file system).

Resuming: the client keeps a sidecar in the output folder, :data:`MANIFEST`, one JSON line per
finished file with the SHA-256 of its input, the settings it was made with and its report row.
A rerun skips a file whose output still exists with the recorded size and whose input hash and
settings are unchanged; ``force`` redoes everything. A file that fails (unreadable, refused by
the codec, or its worker died) gets ``status = "failed"`` and the one-line error the
single-file command prints; the others go on.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import importlib.util
import io
import json
import logging
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import psutil
from distributed import Client, LocalCluster, as_completed, get_worker
from tqdm import tqdm

from ..codec.decoder import check, decode
from ..codec.encoder import encode
from ..format.fields import FORMAT_VERSION, KINDS, Kind
from ..format.limits import decoder_memory, encoder_memory, tile_side
from ..io.files import MESH_SUFFIXES, SUFFIXES, image_shape, read_array, write_atomic
from ..metrics import angular_error, bits_per_pixel, psnr
from ..runtime.threads import CORES
from ..surfaces.codec import decode_mesh, encode_mesh, load_mesh
from ..surfaces.metrics import hausdorff_psnr

__all__ = [
    "COLUMNS",
    "IMAGE_SUFFIXES",
    "MANIFEST",
    "Job",
    "batch",
    "collect_inputs",
    "compress_file",
    "memory_estimate",
]

#: Columns of the report, one row per input. ``bpp`` is for images, ``bpv`` (bits per vertex of
#: the input mesh) for meshes; ``psnr`` is the image PSNR of the kind, or the Hausdorff PSNR of
#: a mesh; the angles (degrees between the source's and the decoded unit normals) are for
#: normal maps only. ``error`` holds the one-line error of a failed file, or the warnings of a
#: compressed one.
COLUMNS = (
    "input",
    "output",
    "kind",
    "status",
    "error",
    "bytes",
    "bpp",
    "bpv",
    "psnr",
    "mean_angle_deg",
    "p99_angle_deg",
    "seconds",
    "worker",
)
#: Inputs read as images; meshes are the suffixes of :data:`bandelets.io.files.MESH_SUFFIXES`.
IMAGE_SUFFIXES = SUFFIXES
#: The sidecar of finished files in the output folder (JSON lines).
MANIFEST = ".bandelets-batch.jsonl"

# Memory of a worker process besides its file: the interpreter, numpy, numba and its compiled
# kernels, trimesh and pymeshlab, distributed (measured: 225 MiB resident after a 64 x 64
# normal map, 326 MiB after a 162-vertex mesh too); rounded up.
_WORKER_BASE = 512 * 2**20
# A mesh: its parameterization and Hausdorff sampling hold a few hundred bytes per byte of the
# input file at most (a rough bound: 200 B/B); the geometry image is at most 1024 x 1024 x 3.
_MESH_PER_BYTE = 200


@dataclass(frozen=True)
class Job:
    """One file of a batch, as :func:`compress_file` receives it on a worker.

    Attributes
    ----------
    input, output : str
        Absolute paths of the input and of the .bdl file to write.
    kind : str
        ``"mesh"``, or the image kind (``"image"``, ``"normal-map"``, ``"geometry-image"``).
    target : dict
        Keyword arguments of the encoder: one of ``bpp``, ``psnr``, ``threshold`` for images;
        ``bits_per_vertex`` or ``bpp`` (or none) for meshes.
    settings : dict
        What the output depends on besides the input's content (kind, target, format
        version), recorded in the sidecar.
    previous : dict or None
        The sidecar's record of this output from an earlier run.
    force : bool
        Redo the file even if ``previous`` says it is up to date, and overwrite an output that
        no earlier run recorded.
    """

    input: str
    output: str
    kind: str
    target: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    previous: dict | None = None
    force: bool = False


def compress_file(job: Job) -> dict:
    """Compress one file: the work of a batch on each file, on whichever worker runs it.

    Never raises for a bad file: the returned record has ``status = "failed"`` and the error.

    Returns
    -------
    dict
        The report row (:data:`COLUMNS`) plus ``sha256`` and ``settings`` for the sidecar.
    """
    start = time.perf_counter()
    row = dict.fromkeys(COLUMNS, None) | {"kind": job.kind, "status": "ok", "error": ""}
    row |= {"settings": job.settings, "worker": _worker_address()}
    try:
        row["sha256"] = _sha256(job.input)
        previous, output = job.previous, Path(job.output)
        if (
            not job.force
            and previous is not None
            and previous.get("sha256") == row["sha256"]
            and previous.get("settings") == row["settings"]
            and output.is_file()
            and output.stat().st_size == previous.get("bytes")
            and _is_bdl(output)
        ):
            measured = {k: previous.get(k) for k in ("bytes", "bpp", "bpv", "psnr")}
            row |= measured | {k: previous.get(k) for k in ("mean_angle_deg", "p99_angle_deg")}
            row["status"] = "skipped"
        else:
            if output.exists() and previous is None and not job.force:
                raise ValueError(f"{job.output}: already exists (use --force to overwrite)")
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                row |= _compress_mesh(job) if job.kind == "mesh" else _compress_image(job)
            row["error"] = "; ".join(f"warning: {w.message}" for w in caught)
    except Exception as err:  # a bad file, whatever the library raised, must not stop the batch
        row |= {"status": "failed", "error": one_line_error(err)}
    row["seconds"] = time.perf_counter() - start
    return row


def _is_bdl(path: Path) -> bool:
    """Whether the file at ``path`` starts as a .bdl file (:func:`bandelets.codec.decoder.check`)."""
    with open(path, "rb") as file:
        return check(file.read(8))


def one_line_error(err: BaseException) -> str:
    """The message ``bandelets`` prints after ``error:`` for ``err`` (type named if unexpected)."""
    text = " ".join(str(err).split()) or type(err).__name__
    return text if isinstance(err, (ValueError, OSError)) else f"{type(err).__name__}: {text}"


def _worker_address() -> str:
    try:
        return get_worker().address
    except ValueError:  # called outside a worker
        return ""


def _sha256(path: str) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()


def _compress_image(job: Job) -> dict:
    array, depth = read_array(job.input, job.kind)
    data = encode(array, **job.target, kind=job.kind, depth=depth)
    _write(job.output, data)
    decoded = decode(data)
    row = {"bytes": len(data), "bpp": bits_per_pixel(len(data), array.shape)}
    row["psnr"] = psnr(array, decoded, job.kind)
    if job.kind == Kind.NORMAL_MAP:
        angles = angular_error(array, decoded)
        row |= {"mean_angle_deg": angles.mean, "p99_angle_deg": angles.p99}
    return row


def _compress_mesh(job: Job) -> dict:
    # pymeshlab's calls run in a thread of their own (bandelets.surfaces.meshlab), not the
    # worker's, where numba's code runs.
    mesh = load_mesh(job.input)
    data = encode_mesh(mesh, **job.target)
    _write(job.output, data)
    row = {"bytes": len(data), "bpv": 8.0 * len(data) / len(mesh.vertices)}
    return row | {"psnr": hausdorff_psnr(mesh, decode_mesh(data))}


def _write(path: str, data: bytes) -> None:
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, data)


# ---------------------------------------------------------------------------------------------
# The client: inputs, sidecar, cluster, report.


def collect_inputs(specs) -> tuple[list[tuple[Path, Path]], list[str]]:
    """The files named by ``specs``: files, folders (walked recursively) and glob patterns.

    A folder yields its images and meshes (:data:`IMAGE_SUFFIXES`, :data:`MESH_SUFFIXES`),
    hidden files and folders left out; so does a pattern, its matches read the same way. A file
    named explicitly is taken whatever its suffix (an unsupported one fails with the reason).

    Returns
    -------
    files : list of (Path, Path)
        Each input and its path relative to the folder or to the fixed part of the pattern
        that found it (its name alone for a file), in the order given, duplicates dropped.
    missing : list of str
        The specs that name nothing.
    """
    files, missing, seen = [], [], set()

    def add(path: Path, relative: Path) -> None:
        key = os.path.realpath(path)
        if key not in seen:
            seen.add(key)
            files.append((path, relative))

    for spec in map(str, specs):
        if glob.has_magic(spec):
            base = _fixed_prefix(spec)
            matches = sorted(Path(m) for m in glob.glob(spec, recursive=True))
            for match in matches:
                for path in _walk(match) if match.is_dir() else [match]:
                    if _supported(path):
                        add(path, path.relative_to(base))
            if not matches:
                missing.append(spec)
        elif Path(spec).is_dir():
            for path in _walk(Path(spec)):
                add(path, path.relative_to(spec))
        elif Path(spec).exists():
            add(Path(spec), Path(Path(spec).name))
        else:
            missing.append(spec)
    return files, missing


def _supported(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in IMAGE_SUFFIXES + MESH_SUFFIXES


def _walk(folder: Path) -> list[Path]:
    found = []
    for root, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        found += [Path(root, n) for n in sorted(names) if not n.startswith(".") and _supported(Path(root, n))]
    return found


def _fixed_prefix(pattern: str) -> Path:
    """The folder part of ``pattern`` before its first wildcard."""
    parts = Path(pattern).parts
    fixed = [p for p in parts[: next(i for i, p in enumerate(parts) if glob.has_magic(p))]]
    return Path(*fixed) if fixed else Path()


def memory_estimate(path: Path, kind: str, target: dict) -> int:
    """Bytes a worker needs for ``path`` beyond its base, from the file's header and
    :func:`bandelets.format.limits.encoder_memory` (0 if the header is unreadable: the worker
    then fails on the file with the reason)."""
    if kind == "mesh":
        side = 1024 if "bits_per_vertex" in target else 256
        return encoder_memory(side, side, 3) + _MESH_PER_BYTE * path.stat().st_size
    shape = _image_shape(path)
    if shape is None:
        return 0
    h, w, c = shape
    # The encoder's peak, the decoder's for the measurement, and the source and decoded arrays.
    tile = tile_side(h, w, c)
    return encoder_memory(h, w, c, tile) + decoder_memory(h, w, c, 1, True, True, tile) + 4 * 8 * h * w * c


def _image_shape(path: Path) -> tuple[int, int, int] | None:
    """The shape an image file's header announces (:func:`bandelets.io.files.image_shape`), or None."""
    try:
        return image_shape(path)
    except ValueError:
        return None


def _read_manifest(path: Path) -> dict[str, dict]:
    records = {}
    if path.is_file():
        for line in path.read_text().splitlines():
            try:
                record = json.loads(line)
                records[record["output"]] = record
            except (ValueError, KeyError, TypeError):  # a line cut short by an interrupted run
                continue
    return records


def _check_report(report: Path, out: Path) -> None:
    suffix = report.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise ValueError(f"{report}: the report must be a .csv or .parquet file")
    if not report.parent.is_dir() and report.parent != out:  # the batch makes ``out``
        raise ValueError(f"{report}: folder {report.parent} does not exist")
    if suffix == ".parquet":
        if importlib.util.find_spec("pyarrow") is None:
            raise ValueError(f"{report}: a Parquet report needs pyarrow (pip install pyarrow)")


def _write_report(frame, report: Path) -> None:
    if report.suffix.lower() == ".parquet":
        buffer = io.BytesIO()
        frame.to_parquet(buffer, index=False)
        write_atomic(report, buffer.getvalue())
    else:
        write_atomic(report, frame.to_csv(index=False).encode())


def _targets(bpp, psnr, threshold, bits_per_vertex) -> tuple[dict, dict]:
    """The encoder's target for images and for meshes; ``ValueError`` if unusable."""
    given = {"bpp": bpp, "psnr": psnr, "threshold": threshold, "bits_per_vertex": bits_per_vertex}
    given = {name: value for name, value in given.items() if value is not None}
    if len(given.keys() - {"bits_per_vertex"}) > 1:
        raise ValueError("give at most one of bpp, psnr or threshold")
    for name, value in given.items():
        if name == "psnr" and not np.isfinite(value):
            raise ValueError(f"psnr must be a finite number, got {value}")
        if name != "psnr" and not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive number, got {value}")
    image = {name: value for name, value in given.items() if name != "bits_per_vertex"} or {"bpp": 1.0}
    mesh = {"bits_per_vertex": bits_per_vertex} if bits_per_vertex is not None else {}
    return image, mesh or ({"bpp": bpp} if bpp is not None else {})


def batch(
    inputs,
    out,
    *,
    bpp: float | None = None,
    psnr: float | None = None,
    threshold: float | None = None,
    kind: str = "image",
    bits_per_vertex: float | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    report: str | os.PathLike | None = None,
    force: bool = False,
    client=None,
    progress: bool = False,
):
    """Compress many images and meshes into .bdl files on a Dask cluster.

    Parameters
    ----------
    inputs : iterable of str or Path
        Files, folders (walked recursively) and glob patterns (:func:`collect_inputs`).
        Images (.png, .npy) and meshes (.obj, .ply, .off, .stl, .glb, .gltf) may be mixed.
    out : str or Path
        Output folder, created if needed. Each output is ``out / relative path`` with the
        suffix ``.bdl``, written atomically.
    bpp, psnr, threshold : float, at most one
        Target of the images (:func:`bandelets.encode`; default 1 bpp).
    kind : {"image", "normal-map", "geometry-image"}
        Kind of the image inputs.
    bits_per_vertex : float, optional
        Target of the meshes (:func:`bandelets.surfaces.codec.encode_mesh`); without it a mesh
        gets ``bpp`` if given, else the mesh coder's default (1 bpp, 256 x 256).
    workers : int, optional
        Worker processes of the local cluster (default: one per core, fewer if memory is
        short). Ignored with ``scheduler`` or ``client``.
    scheduler : str, optional
        Address of an existing ``dask.distributed`` scheduler, e.g. ``tcp://host:8786``.
    report : str or Path, optional
        Report file, ``.csv`` or ``.parquet`` (needs pyarrow); default ``out / "report.csv"``.
    force : bool
        Redo every file, even those an earlier run left up to date.
    client : distributed.Client, optional
        Use this client (its cluster) instead of making one.
    progress : bool
        One progress bar over the files, with the count of failures and an ETA.

    Returns
    -------
    pandas.DataFrame
        The report (:data:`COLUMNS`), one row per input, in input order.

    Raises
    ------
    ValueError
        Bad arguments, no input, or a report that cannot be written; never for a bad file.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown kind {kind!r}; choose one of {', '.join(KINDS)}")
    image_target, mesh_target = _targets(bpp, psnr, threshold, bits_per_vertex)
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: not a folder")
    report = Path(report) if report is not None else out / "report.csv"
    files, missing = collect_inputs(inputs)
    if not files and not missing:
        raise ValueError("no images or meshes found in the inputs")
    _check_report(report, out)

    manifest = out / MANIFEST
    previous = _read_manifest(manifest)

    rows = {spec: _failed(spec, "", "", f"{spec}: no such file") for spec in missing}
    entries, owners = [], {}  # entries: (input as found, output, sidecar key, job)
    for path, relative in files:
        key = relative.with_suffix(".bdl").as_posix()
        output = out / key
        file_kind = "mesh" if path.suffix.lower() in MESH_SUFFIXES else kind
        if key in owners:  # a.png and a.obj, or the same name in two folders
            message = f"{output}: also the output of {owners[key]}; rename one of them"
            rows[str(path)] = _failed(str(path), str(output), file_kind, message)
            continue
        owners[key] = str(path)
        target = mesh_target if file_kind == "mesh" else image_target
        settings = {"kind": file_kind, **target, "format_version": FORMAT_VERSION}
        paths = os.path.abspath(path), os.path.abspath(output)
        entries.append(
            (str(path), str(output), key, Job(*paths, file_kind, target, settings, previous.get(key), force))
        )
    entries.sort(key=lambda entry: -_size(entry[3].input))  # large files first

    bar = tqdm(total=len(rows) + len(entries), unit="file", disable=not progress)
    bar.update(len(rows))
    failures = len(rows)
    bar.set_postfix_str(f"{failures} failed")
    need = max((memory_estimate(Path(e[3].input), e[3].kind, e[3].target) for e in entries), default=0)
    with bar, _client(client, scheduler, workers, need) as dask_client:
        out.mkdir(parents=True, exist_ok=True)  # once the cluster is there: nothing left if not
        rows |= _run(dask_client, entries, previous, manifest, bar, failures)
    # The sidecar again with one line per output, however many runs appended to it.
    write_atomic(manifest, "".join(json.dumps(r) + "\n" for r in previous.values()).encode())

    frame = pd.DataFrame([rows[str(p)] for p, _ in files if str(p) in rows] + [rows[m] for m in missing])
    frame = frame.reindex(columns=list(COLUMNS))
    frame["bytes"] = frame["bytes"].astype("Int64")
    _write_report(frame, report)
    return frame


def _run(client, entries: list, previous: dict, manifest: Path, bar, failures: int) -> dict[str, dict]:
    """Compress the files of ``entries`` on ``client``'s cluster; their report rows by input.

    Each finished file's record goes into ``previous`` and onto the sidecar ``manifest`` at once.
    """
    rows = {}
    # Dask runs the highest priority first: the largest file.
    futures = {
        client.submit(compress_file, entry[3], priority=len(entries) - rank, pure=False): entry
        for rank, entry in enumerate(entries)
    }
    with open(manifest, "a") as sidecar:
        for future in as_completed(futures):
            found, output, key, job = futures.pop(future)
            try:
                row = future.result()
            except Exception as err:  # the worker died (out of memory?) or the cluster went away
                row = _failed(found, output, job.kind, f"worker failed: {one_line_error(err)}")
            row |= {"input": found, "output": output}
            # Name the files as the user did, as the single-file command would.
            row["error"] = row["error"].replace(job.input, found).replace(job.output, output)
            rows[found] = row
            if row["status"] == "failed":
                failures += 1
                bar.set_postfix_str(f"{failures} failed")
            else:
                previous[key] = _record(row, key)
                sidecar.write(json.dumps(previous[key]) + "\n")
                sidecar.flush()  # an interrupted batch keeps what it finished
            bar.update()
    return rows


def _size(path: str) -> int:
    try:
        return os.stat(path).st_size
    except OSError:
        return 0


def _failed(found: str, output: str, kind: str, error: str) -> dict:
    row = dict.fromkeys(COLUMNS, None)
    return row | {"input": found, "output": output, "kind": kind, "status": "failed", "error": error}


def _record(row: dict, key: str) -> dict:
    """The sidecar's line for a finished file."""
    kept = ("sha256", "settings", "bytes", "bpp", "bpv", "psnr", "mean_angle_deg", "p99_angle_deg")
    return {"output": key} | {k: row[k] for k in kept}


@contextlib.contextmanager
def _client(client, scheduler: str | None, workers: int | None, need: int):
    """The Dask client to submit to: ``client``, one connected to ``scheduler``, or a new
    ``LocalCluster`` of processes sized for a file needing ``need`` bytes."""
    if client is not None:
        yield client
        return
    if scheduler is not None:
        with Client(scheduler, timeout="10s") as remote:
            yield remote
        return
    cores = CORES
    total = psutil.virtual_memory().total
    # Dask pauses a worker at 80 % of its limit and restarts it at 95 %: the estimate stays below.
    limit = min(total, int((_WORKER_BASE + need) / 0.8))
    n = workers or max(1, min(cores, total // limit))
    with (
        LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            memory_limit=limit,
            host="127.0.0.1",
            dashboard_address=None,
            silence_logs=logging.CRITICAL,  # not the workers' shutdown chatter
            # One process per core: numba's parallel loops get the cores left over, not all of them.
            env={"NUMBA_NUM_THREADS": str(max(1, cores // n))},
        ) as cluster,
        Client(cluster) as local,
    ):
        yield local
