"""Validation at the door: the checks every input and option passes before any work on it."""

from __future__ import annotations

import numpy as np

from .bitstream import (
    KINDS,
    MAX_MEMORY,
    MAX_NORMAL_WEIGHT,
    MIN_NORMAL_WEIGHT,
    TRANSFORMS,
    TRANSFORMS_1D,
    WAVELETS,
)
from .memory import encoder_memory
from .wavelets import check_extension

__all__ = ["check_image", "check_options", "check_geometry_options", "geometry_options"]


def check_image(array, kind: str, max_memory: int = MAX_MEMORY) -> np.ndarray:
    """Validate an image and return it as float64 ``(H, W, C)``; ``ValueError`` if unusable.

    An image whose encoding would need more than ``max_memory`` bytes
    (:func:`bandelets.memory.encoder_memory`) is refused before any work on it (a float64
    array is not copied; another dtype is converted first).
    """
    if kind not in KINDS:
        raise ValueError(f"unknown kind {kind!r}; choose one of {', '.join(KINDS)}")
    try:
        x = np.asarray(array, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"input is not a numeric array ({err})") from None
    if x.ndim == 2:
        x = x[..., None]
    if x.ndim != 3 or not 1 <= x.shape[2] <= 4:
        raise ValueError(f"expected an H x W or H x W x C array with 1 to 4 channels, got shape {x.shape}")
    if x.shape[0] * x.shape[1] < 2:
        raise ValueError(f"image is too small ({x.shape[1]} x {x.shape[0]} pixels)")
    if kind != "image" and x.shape[2] != 3:
        raise ValueError(f"a {kind} needs 3 channels, got {x.shape[2]}")
    need = encoder_memory(*x.shape)
    if need > max_memory:
        raise ValueError(
            f"encoding a {x.shape[1]} x {x.shape[0]} x {x.shape[2]} image needs about "
            f"{need / 2**20:.0f} MiB, above the limit of {max_memory / 2**20:.0f} MiB (max_memory)"
        )
    if not np.all(np.isfinite(x)):
        raise ValueError("input contains NaN or infinite values")
    return x


def check_options(threshold: float, transform: str, wavelet: str, transform_1d: str) -> None:
    """``ValueError`` unless the transform options are usable."""
    if transform not in TRANSFORMS:
        raise ValueError(f"unknown transform {transform!r}; choose one of {', '.join(TRANSFORMS)}")
    if wavelet not in WAVELETS:
        raise ValueError(f"unknown wavelet {wavelet!r}; choose one of {', '.join(WAVELETS)}")
    if transform_1d not in TRANSFORMS_1D:
        raise ValueError(f"unknown 1D transform {transform_1d!r}; choose one of {', '.join(TRANSFORMS_1D)}")
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError(f"threshold must be a positive number, got {threshold}")


def check_geometry_options(normal_weight: float, extension: str) -> None:
    """``ValueError`` unless ``normal_weight`` and ``extension`` are usable for geometry images."""
    if not (np.isfinite(normal_weight) and MIN_NORMAL_WEIGHT <= normal_weight <= MAX_NORMAL_WEIGHT):
        raise ValueError(f"normal_weight must be from 1/64 to 64, got {normal_weight}")
    check_extension((2, 2), "cdf97", 1, extension)


def geometry_options(
    kind: str, shape: tuple[int, int], wavelet: str, frames: bool, weight: float, extension: str
) -> dict:
    """The geometry-image fields of the header (``{}`` for other kinds); ``ValueError`` if unusable."""
    if kind != "geometry-image":
        if frames or extension != "symmetric":
            raise ValueError("local frames and the spherical extension apply to geometry images only")
        return {}
    check_geometry_options(weight, extension)
    check_extension(shape, wavelet, 1, extension)  # the encoder then picks levels that fit
    return {"extension": extension, "frames": bool(frames), "normal_weight": float(weight) if frames else 1.0}
