"""``bandelets rd``: rate-distortion curves of bandelets against other codecs.

Every point is a real file: the codec encodes at a target rate, the file is written, read
back and decoded, ``bpp = 8 * bytes / (H * W)`` and the PSNR (:func:`bandelets.metrics.psnr`
for the input's kind) is measured on what was decoded. The curves are compared by their
BD-PSNR against bandelets, and ``--decay`` fits the slope of ``log MSE`` against
``log bits``, the exponent of the paper's decay theorems.

An input of 8 or 16-bit samples whose lossless file fits a target is coded losslessly
(:mod:`bandelets.coding.lossless`): that point has an infinite PSNR, at its own rate, below the target,
and the tables print ``lossless`` for it. The BD-PSNR, the ranges and the slopes take the finite
points of each curve only, over the rates both curves cover: a curve that turns lossless is
cut there.

A mesh input (OBJ, PLY, OFF, STL, ...) is compared at equal file size too, with the rate in
bits per vertex of the original mesh (``bpv = 8 * bytes / V``) and the Hausdorff PSNR
(:func:`bandelets.surfaces.metrics.hausdorff_psnr`) of each decoded mesh against the
original: bandelets and wavelets code its spherical geometry image (parameterized once per
mesh, sampled once per side; neither time is in ``encode_s``) of the side ``--size`` or, by
default, the side the mesh coder picks for each rate
(:func:`bandelets.surfaces.codec.auto_size`), Draco (:mod:`bandelets.surfaces.draco`) the
mesh itself.
"""

from __future__ import annotations

import csv
import io
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from .. import samples
from ..codec.decoder import decode
from ..codec.encoder import encode
from ..format.checks import check_image
from ..format.fields import Kind
from ..format.samples import from_samples
from ..io.files import MESH_SUFFIXES, read_array, write_atomic
from ..metrics import angular_error, bd_psnr, bits_per_pixel, psnr
from . import anchors
from .plots import rate_key, rd_figure

__all__ = [
    "CODECS",
    "MESH_CODECS",
    "SAMPLES",
    "MeshSource",
    "Source",
    "check_codecs",
    "decay_slopes",
    "format_points",
    "format_summary",
    "gains",
    "load",
    "run",
]

#: Codecs ``rd`` knows: the bandelet codec, the same codec without geometry, the anchors.
CODECS = ("bandelet", "wavelet", *anchors.ANCHORS)

#: Codecs of mesh inputs: bandelets and wavelets on the geometry image, Draco on the mesh.
MESH_CODECS = ("bandelet", "wavelet", "draco")


#: Generated inputs, ``sample:NAME[@SIZE]``: the generator of each and the kind it is.
SAMPLES = {
    "crease": (samples.crease_normal_map, "normal-map"),
    "bumps": (samples.bump_normal_map, "normal-map"),
    "bevel": (samples.bevel_normal_map, "normal-map"),
    "edge-step": (lambda size: samples.blurred_edge(size, "step"), "image"),
    "edge-tangent": (lambda size: samples.blurred_edge(size, "tangent"), "image"),
}

#: Side of a generated input when the name gives none.
SAMPLE_SIZE = 256

_COLUMNS = ("input", "codec", "target", "bytes", "bpp", "psnr", "encode_s", "decode_s")
# For meshes, also the side of the geometry image a point was coded on (empty for Draco).
_MESH_COLUMNS = (*("bpv" if c == "bpp" else c for c in _COLUMNS), "side")
# For normal maps, the angular error in degrees (metrics.angular_error; empty for other kinds).
_ANGLE_COLUMNS = ("angle_mean", "angle_p99", "angle_max")


@dataclass(frozen=True)
class Source:
    """One input of a run: its label, values, kind and PNG bit depth (0: float)."""

    name: str
    array: np.ndarray
    kind: str
    depth: int = 0


@dataclass(frozen=True)
class MeshSource:
    """A mesh input: its label, the mesh, its spherical parameterization (and the seconds
    that took), the geometry-image side (``None``: chosen per rate by
    :func:`bandelets.surfaces.codec.auto_size`) and the images sampled so far, by side."""

    name: str
    mesh: object  # trimesh.Trimesh
    spherical: object  # bandelets.surfaces.codec.SphericalMesh
    size: int | None
    image_s: float
    images: dict = field(default_factory=dict, compare=False, repr=False)

    def side(self, rate: float) -> int:
        """Side of the geometry image coded at ``rate`` bits per vertex."""
        from ..surfaces.codec import auto_size

        return self.size or auto_size(rate * len(self.mesh.vertices))

    def image(self, side: int) -> np.ndarray:
        """The ``side x side`` geometry image (positions), sampled once."""
        if side not in self.images:
            from ..surfaces.codec import sample_geometry_image

            self.images[side] = sample_geometry_image(self.spherical, side).positions
        return self.images[side]


def load(spec: str, kind: str = "image", size: int | None = None) -> Source | MeshSource:
    """Read a PNG / .npy path or a mesh, or generate ``sample:NAME[@SIZE]`` (which has its own kind).

    A mesh (a path ending in one of :data:`MESH_SUFFIXES`) is checked and parameterized here,
    once for all its points; its geometry images are ``size`` x ``size``, or of the side
    :func:`bandelets.surfaces.codec.auto_size` chooses for each rate.

    Raises
    ------
    ValueError
        Unknown sample, bad size, an unreadable file or one the codec cannot take.
    """
    if Path(spec).suffix.lower() in MESH_SUFFIXES:
        from ..surfaces.codec import check_size, load_mesh, map_to_sphere

        mesh = load_mesh(spec)
        start = time.perf_counter()
        try:
            if size is not None:
                check_size(size)
            spherical = map_to_sphere(mesh)
        except ValueError as err:
            raise ValueError(f"{spec}: {err}") from None
        return MeshSource(Path(spec).stem, mesh, spherical, size, time.perf_counter() - start)
    if not spec.startswith("sample:"):
        array, depth = read_array(spec, kind)
        try:  # here, so that a bad input stops the run instead of skipping its every point
            check_image(array, kind)
        except ValueError as err:
            raise ValueError(f"{spec}: {err}") from None
        return Source(Path(spec).stem, array, kind, depth)
    name, _, size = spec[len("sample:") :].partition("@")
    if name not in SAMPLES:
        raise ValueError(f"unknown sample {name!r}; choose one of {', '.join(SAMPLES)}")
    if size and not (size.isdigit() and 16 <= int(size) <= 4096):
        raise ValueError(f"{spec}: the size must be an integer from 16 to 4096")
    side = int(size or SAMPLE_SIZE)
    make, sample_kind = SAMPLES[name]
    array = make(side)
    if array.dtype == np.uint8:  # 8-bit samples (the bevel map), measured as the PNG they stand for
        return Source(f"{name}@{side}", from_samples(array, sample_kind, 8), sample_kind, 8)
    return Source(f"{name}@{side}", array, sample_kind)


def _encode(source: Source, codec: str, rate: float) -> bytes:
    if codec in anchors.ANCHORS:
        return anchors.encode(source.array, rate, codec, source.kind, source.depth)
    # The encoder picks the better of CDF 9/7 and Haar for each point (encoder.AUTO_CANDIDATES);
    # "wavelet" is the same coder without any geometry: no directional lifting either.
    lifting = None if codec == "bandelet" else False
    return encode(
        source.array,
        bpp=rate,
        transform=codec,
        kind=source.kind,
        depth=source.depth,
        wavelet="auto",
        lifting=lifting,
    )


def _decode(source: Source, codec: str, data: bytes) -> np.ndarray:
    if codec in anchors.ANCHORS:
        return anchors.decode(data, codec, source.array, source.kind, source.depth)
    return decode(data)


def _encode_mesh(source: MeshSource, codec: str, rate: float) -> bytes:
    if codec == "draco":
        from ..surfaces import draco

        return draco.encode(source.mesh, rate * len(source.mesh.vertices) / 8)
    from ..surfaces.codec import encode_mesh

    return encode_mesh(
        source.mesh, image=source.image(source.side(rate)), bits_per_vertex=rate, transform=codec
    )


def _decode_mesh(codec: str, data: bytes):
    if codec == "draco":
        from ..surfaces import draco

        return draco.decode(data)
    from ..surfaces.codec import decode_mesh

    return decode_mesh(data)


def _point(source: Source | MeshSource, codec: str, rate: float, folder: Path) -> dict:
    """Encode, write, read back, decode and measure one point."""
    meshes = isinstance(source, MeshSource)
    start = time.perf_counter()
    data = _encode_mesh(source, codec, rate) if meshes else _encode(source, codec, rate)
    encode_s = time.perf_counter() - start
    unit = "bpv" if meshes else "bpp"
    extension = "drc" if codec == "draco" else anchors.EXTENSIONS.get(codec, "bdl")
    path = folder / f"{codec}-{rate:g}{unit}.{extension}"
    write_atomic(path, data)
    written = path.read_bytes()
    start = time.perf_counter()
    decoded = _decode_mesh(codec, written) if meshes else _decode(source, codec, written)
    decode_s = time.perf_counter() - start
    if meshes:
        from ..surfaces.metrics import hausdorff_psnr

        rate_value = 8 * len(written) / len(source.mesh.vertices)
        quality = hausdorff_psnr(source.mesh, decoded)
        side = {"side": "" if codec == "draco" else source.side(rate)}
    else:
        rate_value = bits_per_pixel(len(written), source.array.shape)
        quality = psnr(source.array, decoded, source.kind)
        side = {}
        if source.kind == Kind.NORMAL_MAP:
            side = dict(zip(_ANGLE_COLUMNS, angular_error(source.array, decoded), strict=True))
    return {
        "input": source.name,
        "codec": codec,
        "target": rate,
        "bytes": len(written),
        unit: rate_value,
        "psnr": quality,
        "encode_s": encode_s,
        "decode_s": decode_s,
        **side,
    }


def check_codecs(codecs: list[str], meshes: bool = False) -> None:
    """Raise ``ValueError`` unless every codec is known for the inputs and installed."""
    known = MESH_CODECS if meshes else CODECS
    unknown = [c for c in codecs if c not in known]
    if unknown:
        inputs = "meshes" if meshes else "images"
        raise ValueError(f"unknown codec {unknown[0]!r} for {inputs}; choose from {', '.join(known)}")
    missing = [c for c in codecs if c in anchors.ANCHORS and not anchors.available(c)]
    if missing:
        raise ValueError(f"imagecodecs was built without {missing[0]}")
    if "draco" in codecs:
        from ..surfaces import draco

        if not draco.available():
            raise ValueError("the draco codec needs DracoPy (pip install DracoPy)")


def run(
    sources: list[Source | MeshSource],
    rates: list[float],
    codecs: list[str],
    out: Path,
    progress: bool = False,
) -> list[dict]:
    """Measure every codec at every rate on every source.

    Writes the files under ``out/INPUT/``, then ``out/rd.csv``, ``out/rd.png`` and, for normal
    maps, ``out/rd-angle.png``. A point
    a codec cannot reach (a target below its smallest file) is skipped with a warning.
    The sources are all images (rates in bits per pixel) or all meshes (bits per vertex).

    Returns
    -------
    list of dict
        One row per point, with the keys of the CSV columns.
    """
    meshes = [isinstance(s, MeshSource) for s in sources]
    if any(meshes) and not all(meshes):
        raise ValueError("give either images or meshes, not both")
    check_codecs(codecs, any(meshes))
    unit = "bpv" if any(meshes) else "bpp"
    if not rates or any(not (np.isfinite(r) and r > 0) for r in rates):
        raise ValueError("rates must be positive numbers")
    names = [s.name for s in sources]
    if len(set(names)) != len(names):
        raise ValueError("two inputs have the same name; rename one")
    for s in sources:
        (out / s.name).mkdir(parents=True, exist_ok=True)
    jobs = [(s, c, r) for s in sources for c in codecs for r in rates]
    rows = []
    for source, codec, rate in tqdm(jobs, desc="rd", disable=not progress):
        try:
            rows.append(_point(source, codec, rate, out / source.name))
        except ValueError as err:
            warnings.warn(f"{source.name}: {codec} at {rate:g} {unit} skipped: {err}", stacklevel=2)
    _write_csv(rows, out / "rd.csv", _MESH_COLUMNS if any(meshes) else _COLUMNS + _ANGLE_COLUMNS)

    rd_figure(rows, out / "rd.png")
    if any("angle_p99" in r for r in rows):  # normal maps: their users judge in degrees
        rd_figure(rows, out / "rd-angle.png", value="angle_p99")
    return rows


def _write_csv(rows: list[dict], path: Path, columns: tuple[str, ...]) -> None:
    text = io.StringIO()
    writer = csv.DictWriter(text, columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: f"{v:.6g}" if isinstance(v, float) else v for k, v in row.items()})
    write_atomic(path, text.getvalue().encode())


def _curve(rows: list[dict], name: str, codec: str) -> tuple[np.ndarray, np.ndarray]:
    """The finite (rate, psnr) points of one curve, by increasing rate."""
    key = rate_key(rows)
    points = sorted((r[key], r["psnr"]) for r in rows if r["input"] == name and r["codec"] == codec)
    points = [p for p in points if np.isfinite(p[1])]
    return np.array([p[0] for p in points]), np.array([p[1] for p in points])


def _pairs(rows: list[dict]) -> list[tuple[str, str]]:
    """(input, codec) of every curve, in the order of the rows."""
    return list(dict.fromkeys((r["input"], r["codec"]) for r in rows))


def gains(rows: list[dict], reference: str = "bandelet") -> list[dict]:
    """BD-PSNR of ``reference`` over every other codec, per input.

    Returns
    -------
    list of dict
        ``input, codec, gain`` (dB; positive when ``reference`` is better; NaN when a curve
        has fewer than four points or the curves do not overlap in rate).
    """
    out = []
    for name, codec in _pairs(rows):
        if codec == reference:
            continue
        ours, theirs = _curve(rows, name, reference), _curve(rows, name, codec)
        gain = float("nan")
        if min(ours[0].size, theirs[0].size) >= 4:
            try:
                gain = bd_psnr(*ours, *theirs)
            except ValueError:  # no common rate range
                pass
        out.append({"input": name, "codec": codec, "gain": gain})
    return out


def decay_slopes(rows: list[dict]) -> list[dict]:
    """Least-squares slope of ``log MSE`` against ``log bits`` of every curve.

    ``MSE = peak**2 10**(-PSNR / 10)``, so the slope is that of ``-PSNR ln(10) / 10``
    against ``ln(8 * bytes)``; the peak drops out. NaN for fewer than two points.
    """
    out = []
    for name, codec in _pairs(rows):
        bpp, quality = _curve(rows, name, codec)
        slope = float("nan")
        if bpp.size >= 2:
            slope = float(np.polyfit(np.log(bpp), -quality * np.log(10) / 10, 1)[0])
        out.append({"input": name, "codec": codec, "slope": slope})
    return out


def _table(header: list[str], lines: list[list[str]]) -> str:
    """A Markdown table, readable as it is on a terminal."""
    widths = [max(len(str(x)) for x in column) for column in zip(header, *lines, strict=True)]
    rule = ["-" * w for w in widths]
    return "\n".join(
        "| " + " | ".join(str(x).ljust(w) for x, w in zip(line, widths, strict=True)) + " |"
        for line in [header, rule, *lines]
    )


def format_points(rows: list[dict]) -> str:
    """Every measured point as a Markdown table (meshes: with the geometry image's side; normal
    maps: with the mean and 99th percentile angular error)."""
    sides = bool(rows) and "side" in rows[0]
    angles = any("angle_mean" in r for r in rows)
    return _table(
        ["input", "codec", "target", "bytes", rate_key(rows), "PSNR dB", "enc s", "dec s"]
        + ["side"] * sides
        + ["mean deg", "p99 deg"] * angles,
        [
            [
                r["input"],
                r["codec"],
                f"{r['target']:g}",
                str(r["bytes"]),
                f"{r[rate_key(rows)]:.4f}",
                "lossless" if np.isinf(r["psnr"]) else f"{r['psnr']:.2f}",
                f"{r['encode_s']:.2f}",
                f"{r['decode_s']:.2f}",
            ]
            + [str(r.get("side", ""))] * sides
            + [f"{r[k]:.2f}" if k in r else "" for k in _ANGLE_COLUMNS[:2]] * angles
            for r in rows
        ],
    )


def format_summary(rows: list[dict], slopes: bool = False) -> str:
    """One line per curve: its rate range, the BD-PSNR of bandelets over it, and the slope."""
    gain = {(g["input"], g["codec"]): g["gain"] for g in gains(rows)}
    slope = {(s["input"], s["codec"]): s["slope"] for s in decay_slopes(rows)}
    header = [
        "input",
        "codec",
        "points",
        f"{rate_key(rows)} range",
        "PSNR range",
        "bandelets' BD-PSNR gain dB",
    ]
    lines = []
    for name, codec in _pairs(rows):
        bpp, quality = _curve(rows, name, codec)
        g = gain.get((name, codec))
        line = [
            name,
            codec,
            str(bpp.size),
            f"{bpp.min():.3f}-{bpp.max():.3f}" if bpp.size else "-",
            f"{quality.min():.2f}-{quality.max():.2f}" if bpp.size else "-",
            "(reference)" if g is None else ("n/a" if np.isnan(g) else f"{g:+.2f}"),
        ]
        if slopes:
            line.append(f"{slope[(name, codec)]:.2f}")
        lines.append(line)
    if slopes:
        header.append("slope of log MSE vs log bits")
    return _table(header, lines)
