"""Regenerate the golden .bdl files of this folder and golden.json.

    python tests/data/make_golden.py            # rewrite the files and golden.json
    python tests/data/make_golden.py --check    # only compare, exit status 1 on a difference

The inputs are closed-form (no random generator, no other module of the package), so they
are the same on every platform. ``golden.json`` holds, for every file, the SHA-256 of the
file and of its decoded array rounded to 6 decimals (:func:`decoded_sha256`).

Rule: a change of the format must keep decoding these files to the same checksums, or bump
``bandelets.format.header.FORMAT_VERSION`` (and then regenerate them). Do not regenerate them to
make a failing decode test pass.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def gray_16() -> np.ndarray:
    """16 x 16 gray image: a blurred oblique edge over a gentle ramp."""
    y, x = np.mgrid[0:16, 0:16].astype(np.float64)
    return 0.5 + 0.4 * np.tanh((0.8 * (y - 7.3) - 0.6 * (x - 8.1)) / 1.5) + 0.01 * x


def normal_map_24x20() -> np.ndarray:
    """24 wide x 20 high normal map with a crease (unit vectors)."""
    y, x = np.mgrid[0:20, 0:24].astype(np.float64)
    d = np.cos(0.4) * (x - 11.7) + np.sin(0.4) * (y - 9.2)
    slope = 0.6 * np.tanh(d / 2.0)
    n = np.stack([-slope * np.cos(0.4), -slope * np.sin(0.4), np.ones_like(x)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def facing_away_16() -> np.ndarray:
    """16 x 16 normal map whose normals face every way (z < 0 on half): three channels coded."""
    v, u = np.mgrid[0:16, 0:16].astype(np.float64) / 15.0
    theta, phi = np.pi * (0.15 + 0.7 * v), 2.5 * u + 0.4 * np.sign(u - 0.45)
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)


def bumps_32() -> np.ndarray:
    """32 x 32 normal map of a smooth bumpy height (a loop filter pays on it)."""
    y, x = np.mgrid[0:32, 0:32].astype(np.float64)
    gy, gx = np.gradient(0.8 * np.sin(x / 2.3) * np.cos(y / 3.1) + 0.5 * np.sin((x + 2 * y) / 4.0))
    n = np.stack([-gx, -gy, np.ones_like(x)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def geometry_image_32() -> np.ndarray:
    """32 x 32 geometry image: positions of a bumped sphere patch."""
    v, u = np.mgrid[0:32, 0:32].astype(np.float64) / 31.0
    theta, phi = np.pi * (0.2 + 0.6 * v), 2 * np.pi * u
    r = 1.0 + 0.1 * np.sin(3 * phi) * np.sin(2 * theta)
    return np.stack([r * np.sin(theta) * np.cos(phi), r * np.sin(theta) * np.sin(phi), r * np.cos(theta)], -1)


def octahedral_32() -> np.ndarray:
    """32 x 32 normal map of an ellipsoid on an octahedral geometry image (the plain octahedral
    unfolding of the sphere: each edge glued to itself reversed), coded folded (format version 14)."""
    v, u = (np.mgrid[0:32, 0:32].astype(np.float64) + 0.5) / 16.0 - 1.0
    z = 1.0 - np.abs(u) - np.abs(v)
    x = np.where(z < 0, (1.0 - np.abs(v)) * np.sign(u), u)
    y = np.where(z < 0, (1.0 - np.abs(u)) * np.sign(v), v)
    n = np.stack([x, y, z], axis=-1) / np.array([1.0, 0.7, 0.4])
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def bumps_32_samples() -> np.ndarray:
    """The bumps map as 8-bit samples (uint8), as a PNG holds it."""
    return np.round((bumps_32() + 1.0) / 2.0 * 255.0).astype(np.uint8)


def gray_16_samples() -> np.ndarray:
    """The gray image as the values of 16-bit samples (as read from a 16-bit PNG)."""
    return np.round(np.clip(gray_16(), 0.0, 1.0) * 65535.0) / 65535.0


#: file name -> (input maker, encode options)
GOLDEN = {
    "gray16.bdl": (gray_16, {"threshold": 0.01, "kind": "image", "transform": "bandelet"}),
    "normal24x20.bdl": (
        normal_map_24x20,
        {"threshold": 0.005, "kind": "normal-map", "transform": "bandelet"},
    ),
    "normal24x20-lifted.bdl": (
        normal_map_24x20,
        {"threshold": 0.005, "kind": "normal-map", "transform": "bandelet", "lifting": True},
    ),
    "normal24x20-tiled.bdl": (
        normal_map_24x20,
        {"threshold": 0.005, "kind": "normal-map", "transform": "bandelet", "tile": 16},
    ),
    "facing16.bdl": (
        facing_away_16,
        {"threshold": 0.1, "kind": "normal-map", "transform": "bandelet"},
    ),
    "facing16-lifted.bdl": (
        facing_away_16,
        {"threshold": 0.1, "kind": "normal-map", "transform": "bandelet", "lifting": True},
    ),
    "bumps32.bdl": (bumps_32, {"threshold": 0.05, "kind": "normal-map", "transform": "bandelet"}),
    # The pair's spectra differ in their last bits with numpy's SIMD kernels (so do the
    # equidistant coordinates): with bandelets, a near tie of two directions of this input went
    # the other way on a baseline CPU, so the pair's file has no direction search.
    "bumps32-riesz.bdl": (
        bumps_32,
        {"threshold": 0.02, "kind": "normal-map", "transform": "wavelet", "riesz": True},
    ),
    "octahedral32.bdl": (octahedral_32, {"threshold": 0.02, "kind": "normal-map", "transform": "bandelet"}),
    "bumps32-lossless.bdl": (bumps_32_samples, {"kind": "normal-map", "lossless": True}),
    "gray16-lossless.bdl": (gray_16_samples, {"kind": "image", "depth": 16, "lossless": True}),
    "geometry32.bdl": (
        geometry_image_32,
        {"threshold": 0.002, "kind": "geometry-image", "transform": "wavelet"},
    ),
    "geometry32-frames.bdl": (
        geometry_image_32,
        {
            "threshold": 0.002,
            "kind": "geometry-image",
            "transform": "bandelet",
            "frames": True,
            "normal_weight": 3.0,
            "extension": "spherical",
        },
    ),
}


def decoded_sha256(decoded: np.ndarray) -> str:
    """SHA-256 of the decoded array rounded to 6 decimals, as little-endian float64.

    Rounding absorbs the last-bit differences of floating point between platforms and
    BLAS builds; ``+ 0.0`` turns -0.0 into 0.0.
    """
    rounded = np.ascontiguousarray(np.round(decoded, 6) + 0.0, dtype="<f8")
    return hashlib.sha256(rounded.tobytes()).hexdigest()


def build() -> dict:
    import bandelets

    entries = {}
    for name, (make, options) in GOLDEN.items():
        data = bandelets.encode(make(), **options)
        decoded = bandelets.decode(data)
        entries[name] = {
            "options": options,
            "bytes": len(data),
            "file_sha256": hashlib.sha256(data).hexdigest(),
            "decoded_shape": list(decoded.shape),
            "decoded_sha256": decoded_sha256(decoded),
            "data": data,
        }
    return entries


def main(argv: list[str]) -> int:
    from bandelets.format.fields import FORMAT_VERSION

    entries = build()
    table = {
        "format_version": FORMAT_VERSION,
        "files": {k: {f: v for f, v in e.items() if f != "data"} for k, e in entries.items()},
    }
    if "--check" in argv:
        stored = json.loads((HERE / "golden.json").read_text())
        same = stored == table and all((HERE / k).read_bytes() == e["data"] for k, e in entries.items())
        print("golden files up to date" if same else "golden files differ")
        return 0 if same else 1
    for name, e in entries.items():
        (HERE / name).write_bytes(e["data"])
    (HERE / "golden.json").write_text(json.dumps(table, indent=2) + "\n")
    print(json.dumps(table, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
