"""Shared fixtures of the bandelets test suite."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest


def straight_edge(
    size: int = 64, angle_deg: float = 30.0, blur: float = 1.5, shape: tuple[int, int] | None = None
) -> np.ndarray:
    """A blurred straight edge (tanh profile) through the centre of the image.

    The edge runs along the direction ``(cos a, sin a)`` in (x = column, y = row)
    coordinates, the convention of :func:`bandelets.transform.geometry.directions`; values are in
    [-1, 1].
    """
    rows, cols = shape or (size, size)
    y, x = np.mgrid[0:rows, 0:cols].astype(np.float64)
    theta = np.deg2rad(angle_deg)
    # Signed distance to the line, slightly off the pixel grid so no sample sits on it.
    distance = -np.sin(theta) * (x - cols / 2 + 0.3) + np.cos(theta) * (y - rows / 2 + 0.2)
    return np.tanh(distance / blur)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def edge_image() -> np.ndarray:
    """64 x 64 straight edge at 30 degrees plus a gentle ramp, values in about [-1, 1.3]."""
    y, x = np.mgrid[0:64, 0:64] / 64.0
    return straight_edge(64) + 0.3 * x - 0.1 * y


@pytest.fixture(scope="session")
def crease_map() -> np.ndarray:
    """The package's synthetic crease normal map, 64 x 64 x 3 unit vectors."""
    from bandelets.samples import crease_normal_map

    return crease_normal_map(64)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared data folder next to the repository (``../shared/data``), or skip."""
    path = Path(__file__).resolve().parents[2] / "shared" / "data"
    if not path.is_dir():
        pytest.skip(f"shared data folder {path} is absent")
    return path
