"""The checks every input passes at the door, before any work on it: the image, the transform
options, the target and the threshold a file may hold.

Raised as ``ValueError`` (``TypeError`` for a target that is no number), with one line that says
what to give instead.
"""

from __future__ import annotations

import numbers

import numpy as np

from .fields import KINDS, MAX_MEMORY, MAX_THRESHOLD, MIN_THRESHOLD, TRANSFORMS, TRANSFORMS_1D, WAVELETS, Kind
from .limits import check_encodable

__all__ = ["check_image", "check_options", "check_targets", "check_threshold"]


def check_image(array, kind: str, max_memory: int = MAX_MEMORY) -> np.ndarray:
    """Validate an image and return it as float64 ``(H, W, C)``; ``ValueError`` if unusable.

    An image whose encoding would need more than ``max_memory`` bytes, or whose file the default
    decoder would refuse, is refused before any work on it
    (:func:`bandelets.format.limits.check_encodable`; a float64 array is not copied, another dtype is
    converted first).
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
    if kind != Kind.IMAGE and x.shape[2] != 3:
        raise ValueError(f"a {kind} needs 3 channels, got {x.shape[2]}")
    check_encodable(*x.shape, max_memory, tile=0)
    if not np.all(np.isfinite(x)):
        raise ValueError("input contains NaN or infinite values")
    return x


def check_options(transform: str, wavelet: str, transform_1d: str, wavelets: tuple = WAVELETS) -> None:
    """``ValueError`` unless the transform options are usable (``wavelet`` one of ``wavelets``)."""
    for what, value, choices in (
        ("transform", transform, TRANSFORMS),
        ("wavelet", wavelet, wavelets),
        ("1D transform", transform_1d, TRANSFORMS_1D),
    ):
        if value not in choices:
            raise ValueError(f"unknown {what} {value!r}; choose one of {', '.join(choices)}")


def check_targets(kind: str, **targets) -> None:
    """``ValueError`` (``TypeError`` for a non-number) unless exactly one of the targets ``bpp``,
    ``threshold``, ``psnr`` and ``max_angle`` is given, and it is usable for ``kind``."""
    if sum(v is not None for v in targets.values()) != 1:
        raise ValueError("give exactly one of bpp, threshold, psnr or max_angle")
    name, value = next((k, v) for k, v in targets.items() if v is not None)
    if not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    if name == "max_angle" and kind != Kind.NORMAL_MAP:
        raise ValueError("max_angle applies to normal maps only")
    if name == "threshold":
        check_threshold(value)
    elif name == "max_angle" and not (np.isfinite(value) and 0 < value < 180):
        raise ValueError(f"max_angle must be a number of degrees from 0 to 180, got {value}")
    elif not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value}")


def check_threshold(threshold: float) -> None:
    """``ValueError`` unless ``threshold`` is a number a file may hold
    (:data:`~bandelets.format.header.MIN_THRESHOLD` to :data:`~bandelets.format.header.MAX_THRESHOLD`)."""
    if not MIN_THRESHOLD <= threshold <= MAX_THRESHOLD:
        raise ValueError(f"threshold must be from {MIN_THRESHOLD:g} to {MAX_THRESHOLD:g}, got {threshold}")
