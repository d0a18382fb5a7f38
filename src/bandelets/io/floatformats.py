"""OpenEXR and TIFF files, the float formats of normal maps (besides PNG and .npy, see
:mod:`bandelets.io.files`).

EXR goes through the ``OpenEXR`` package (the reference library's bindings), TIFF through
``tifffile``; both are imported when a file of theirs is met (not for a PNG, nor before the
command line has checked its arguments). Samples come back as they are
stored: floats (EXR half or float, TIFF float) with depth 0, and TIFF integer samples of 8 or
16 bits with that depth, which :mod:`bandelets.io.files` maps to values as it does PNG samples.
"""

from __future__ import annotations

import io
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = ["read_exr", "read_tiff", "write_exr", "write_tiff"]

# EXR channel names in the order they are read; anything else is refused.
_EXR_ORDERS = (("R", "G", "B", "A"), ("X", "Y", "Z"), ("Y",))


def read_exr(path: Path) -> np.ndarray:
    """The channels of an EXR file, float, shape (H, W) or (H, W, C): R, G, B (an alpha dropped
    with a warning), X, Y, Z, or Y (gray), as many of them as it has."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path), separate_channels=True) as exr:
            channels = {name: c.pixels for name, c in exr.channels().items()}
    except Exception as err:  # the bindings raise RuntimeError, and others for odd files
        raise ValueError(f"{path}: not a readable OpenEXR file ({err})") from None
    for order in _EXR_ORDERS:
        names = [n for n in order if n in channels]
        if names and set(channels) <= set(order):
            break
    else:
        raise ValueError(f"{path}: unsupported EXR channels {', '.join(sorted(channels))}; use R, G, B or Y")
    if names[-1] == "A" and len(names) > 1:
        warnings.warn(f"{path}: alpha channel dropped", stacklevel=3)
        names = names[:-1]
    planes = [channels[n] for n in names]
    if any(p.dtype.kind != "f" for p in planes):
        raise ValueError(f"{path}: EXR channels of integer type are not supported; use half or float")
    return planes[0] if len(planes) == 1 else np.stack(planes, axis=-1)


def exr_shape(path: Path) -> tuple[int, int, int]:
    """Height, width and channel count an EXR file's header announces (no pixel read)."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path), header_only=True) as exr:
            header = exr.header()
            low, high = header["dataWindow"]
            channels = len(header["channels"])
    except Exception as err:  # the bindings raise RuntimeError, and others for odd files
        raise ValueError(f"{path}: not a readable OpenEXR file ({err})") from None
    return int(high[1] - low[1] + 1), int(high[0] - low[0] + 1), channels


def write_exr(path: str, values: np.ndarray) -> None:
    """Write float32 values to ``path``: (H, W) as Y, (H, W, C) as R, G[, B[, A]], ZIP compressed."""
    import OpenEXR

    values = np.asarray(values, np.float32)
    planes = [values] if values.ndim == 2 else [values[..., k] for k in range(values.shape[2])]
    names = ("Y",) if values.ndim == 2 else ("R", "G", "B", "A")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {n: np.ascontiguousarray(p) for n, p in zip(names, planes, strict=False)}
    with OpenEXR.File(header, channels) as exr:
        exr.write(path)


def tiff_shape(series) -> tuple[int, int, int]:
    """Height, width and samples per pixel of a tifffile series, from its header."""
    sizes = dict(zip(series.axes, series.shape, strict=True))
    return sizes.get("Y", 1), sizes.get("X", 1), sizes.get("S", 1)


def read_tiff(
    path: Path, check_shape: Callable[[tuple[int, ...]], None] | None = None
) -> tuple[np.ndarray, int]:
    """The samples of a single-image TIFF file and their depth: (uint8 or uint16 samples, 8 or 16)
    or (floats, 0); shape (H, W) or (H, W, C). ``check_shape`` is given the (H, W, C) the header
    announces (:func:`tiff_shape`) before any sample is read."""
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            if len(tif.series) != 1 or len(tif.series[0].levels) != 1:
                raise ValueError("holds several images; give one")
            page = tif.series[0]
            if check_shape is not None:
                check_shape(tiff_shape(page))
            samples = page.asarray()
            planar = page.keyframe.planarconfig == tifffile.PLANARCONFIG.SEPARATE
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None
    except Exception as err:  # tifffile raises TiffFileError and others for bad data
        raise ValueError(f"{path}: not a readable TIFF file ({err})") from None
    if planar and samples.ndim == 3:
        samples = np.moveaxis(samples, 0, -1)
    if samples.ndim not in (2, 3):
        raise ValueError(f"{path}: unsupported TIFF image of shape {samples.shape}")
    if samples.dtype in (np.uint8, np.uint16):
        return samples, 8 * samples.dtype.itemsize
    if samples.dtype.kind == "f":
        return samples, 0
    raise ValueError(f"{path}: unsupported TIFF sample type {samples.dtype}; use 8 or 16-bit or float")


def write_tiff(samples: np.ndarray) -> bytes:
    """A TIFF file (zlib compressed) of uint8, uint16 or float32 samples, (H, W) or (H, W, C)."""
    import tifffile

    buffer = io.BytesIO()
    rgb = samples.ndim == 3 and samples.shape[2] in (3, 4)
    tifffile.imwrite(
        buffer,
        samples,
        photometric="rgb" if rgb else "minisblack",
        planarconfig="contig",
        compression="zlib",
        extrasamples=("unassalpha",) if rgb and samples.shape[2] == 4 else None,
    )
    return buffer.getvalue()
