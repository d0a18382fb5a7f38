"""Validation at the door: the options of the encoder, and the checks every input passes before any
work on it.

:class:`EncodeOptions` is built once from the keywords of :func:`bandelets.encode` (or of
:func:`bandelets.surfaces.codec.encode_mesh`), validated on construction, and passed down.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..format.header import (
    DEFAULT_NORMAL_WEIGHT,
    DEFAULT_TRANSFORM_1D,
    DEFAULT_WAVELET,
    KINDS,
    MAX_MEMORY,
    MAX_NORMAL_WEIGHT,
    MAX_THRESHOLD,
    MAX_WORK,
    MIN_NORMAL_WEIGHT,
    MIN_THRESHOLD,
    TRANSFORMS,
    TRANSFORMS_1D,
    WAVELETS,
    Kind,
    Transform1D,
    Wavelet,
)
from ..format.limits import check_encodable
from ..transform.wavelets import check_extension
from .tiles import MIN_TILE

__all__ = [
    "AUTO_WAVELET",
    "EncodeOptions",
    "check_image",
    "check_options",
    "check_targets",
    "check_threshold",
    "geometry_options",
]

#: The ``wavelet`` that lets the encoder choose, per image and target, among
#: :data:`bandelets.codec.encoder.AUTO_CANDIDATES`.
AUTO_WAVELET = "auto"


@dataclass(frozen=True, kw_only=True)
class EncodeOptions:
    """How to encode an image: every choice of :func:`bandelets.encode` but the target.

    The attributes are the keywords of :func:`bandelets.encode`, with the same defaults, and
    ``mesh_vertices``: the vertex count of the mesh a geometry image was sampled from, which
    :func:`bandelets.surfaces.codec.encode_mesh` records for its decoder (0: none).
    ``ValueError`` on construction if any is unusable (whatever the image).

    Examples
    --------
    >>> EncodeOptions(kind="normal-map").wavelet
    'cdf97'
    >>> EncodeOptions(wavelet="db3")
    Traceback (most recent call last):
    ...
    ValueError: unknown wavelet 'db3'; choose one of cdf97, haar, db2, db4, db6, db8, auto
    """

    transform: str = "bandelet"
    kind: Kind = "image"
    wavelet: Wavelet | Literal["auto"] = DEFAULT_WAVELET
    transform_1d: Transform1D = DEFAULT_TRANSFORM_1D
    depth: int = 0
    frames: bool = False
    normal_weight: float = DEFAULT_NORMAL_WEIGHT
    extension: str = "symmetric"
    restore: bool = True
    loop_filter: bool = True
    lifting: bool | None = None
    progress: bool = False
    max_memory: int = MAX_MEMORY
    xy: bool = False
    max_work: int = MAX_WORK
    mesh_vertices: int = 0
    tile: int = 0
    lossless: bool | None = None
    riesz: bool | None = None

    def __post_init__(self) -> None:
        if self.lossless not in (None, True, False):
            raise ValueError(f"lossless must be None, True or False, got {self.lossless!r}")
        if self.lossless and self.kind == "geometry-image":
            raise ValueError("a geometry image has float positions: it has no lossless coding")
        if not (isinstance(self.tile, (int, np.integer)) and (self.tile == 0 or self.tile >= MIN_TILE)):
            raise ValueError(
                f"tile must be 0 (automatic) or an integer of at least {MIN_TILE}, got {self.tile!r}"
            )
        if self.kind not in KINDS:
            raise ValueError(f"unknown kind {self.kind!r}; choose one of {', '.join(KINDS)}")
        if self.xy and self.kind != "normal-map":
            raise ValueError("xy applies to normal maps only")
        if self.riesz not in (None, True, False):
            raise ValueError(f"riesz must be None, True or False, got {self.riesz!r}")
        if self.riesz and self.kind != "normal-map":
            raise ValueError("riesz applies to normal maps only (their two channels)")
        if self.riesz and self.lifting:
            raise ValueError("a Riesz pair is not lifted along directions: give riesz or lifting, not both")
        if self.depth not in (0, 8, 16):
            raise ValueError(f"depth must be 0, 8 or 16, got {self.depth}")
        check_options(self.transform, self.wavelet, self.transform_1d, wavelets=(*WAVELETS, AUTO_WAVELET))
        if self.lifting and (self.wavelet not in ("cdf97", AUTO_WAVELET) or self.kind == "geometry-image"):
            raise ValueError(
                f"directional lifting needs the cdf97 wavelet and an image or a normal map, got "
                f"{self.wavelet} and a {self.kind}"
            )
        if self.kind != "geometry-image":
            if self.frames or self.extension != "symmetric" or self.mesh_vertices:
                raise ValueError(
                    "local frames, the spherical extension and mesh vertices apply to geometry images only"
                )
            return
        if not (isinstance(self.mesh_vertices, (int, np.integer)) and self.mesh_vertices in range(2**32)):
            raise ValueError(
                f"mesh_vertices must be an integer from 0 to 2**32 - 1, got {self.mesh_vertices}"
            )
        if 0 < self.mesh_vertices < 4:
            raise ValueError(f"a closed mesh has at least 4 vertices, got mesh_vertices={self.mesh_vertices}")
        weight = self.normal_weight
        if not (np.isfinite(weight) and MIN_NORMAL_WEIGHT <= weight <= MAX_NORMAL_WEIGHT):
            raise ValueError(f"normal_weight must be from 1/64 to 64, got {weight}")
        check_extension((2, 2), "cdf97", 1, self.extension)


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
    if kind != "image" and x.shape[2] != 3:
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
    if name == "max_angle" and kind != "normal-map":
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


def geometry_options(options: EncodeOptions, shape: tuple[int, int]) -> dict:
    """The geometry-image fields of the header (``{}`` for other kinds); ``ValueError`` if an
    image of ``shape`` cannot have the options' extension."""
    if options.kind != "geometry-image":
        return {}
    check_extension(shape, options.wavelet, 1, options.extension)  # the encoder then picks levels that fit
    weight = float(options.normal_weight) if options.frames else 1.0
    return {
        "extension": options.extension,
        "frames": bool(options.frames),
        "normal_weight": weight,
        "mesh_vertices": int(options.mesh_vertices),
    }
