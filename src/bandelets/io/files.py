"""Reading and writing the arrays the command line works on: PNG, .npy, OpenEXR and TIFF
(the last two through :mod:`bandelets.io.floatformats`).

PNG samples are mapped to [0, 1] for images and to [-1, 1] for normal maps (``2 v - 1``),
and mapped back the same way, at the bit depth recorded in the .bdl file. PNG coding goes
through ``imagecodecs`` (libpng), which reads and writes 16-bit RGB.
"""

from __future__ import annotations

import io
import os
import struct
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..format.fields import Kind
from ..format.limits import MAX_MEMORY, check_encodable
from ..format.samples import as_read, from_samples, integer_samples, to_samples
from . import tempfiles
from .floatformats import exr_shape, read_exr, read_tiff, tiff_shape, write_exr, write_tiff
from .stderrhold import held_stderr

__all__ = [
    "MESH_SUFFIXES",
    "SUFFIXES",
    "as_read",
    "check_suffix",
    "from_samples",
    "image_shape",
    "integer_samples",
    "png_shape",
    "read_array",
    "to_samples",
    "write_array",
    "write_atomic",
]


#: Suffixes of the files read and written: PNG (8 or 16-bit), .npy, OpenEXR, TIFF (8, 16-bit, float).
SUFFIXES = (".png", ".npy", ".exr", ".tif", ".tiff")
#: File suffixes read as meshes (through trimesh).
MESH_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")
# Lossy 8-bit formats: their artefacts would be coded as detail.
_REFUSED = {".jpg": "JPEG", ".jpeg": "JPEG", ".webp": "WebP"}


def check_suffix(path: str | os.PathLike, what: str = "input") -> None:
    """``ValueError`` unless ``path`` ends in one of :data:`SUFFIXES` (``what``: input or output)."""
    suffix = Path(path).suffix.lower()
    if what == "input" and suffix in _REFUSED:
        raise ValueError(
            f"{path}: {_REFUSED[suffix]} inputs are refused (lossy: their artefacts would be coded as "
            "detail); give the original as PNG, TIFF, EXR or .npy"
        )
    if suffix not in SUFFIXES:
        raise ValueError(
            f"{path}: unsupported {what} format {suffix or '(none)'}; use {', '.join(SUFFIXES[:-1])}"
        )


def read_array(path: str | os.PathLike, kind: str, max_memory: int = MAX_MEMORY) -> tuple[np.ndarray, int]:
    """Read a PNG, .npy, EXR or TIFF file (:data:`SUFFIXES`).

    Integer samples of PNG and TIFF files (and ``uint8`` / ``uint16`` .npy normal maps) are
    mapped to [0, 1], or [-1, 1] for a normal map; floats are taken as they are.

    An image the encoder would refuse (:func:`bandelets.format.limits.check_encodable` with
    ``max_memory``) is refused from its header, before its samples are decoded: a few hundred
    kilobytes of PNG can hold gigabytes of samples.

    Returns
    -------
    array : ndarray, float64, (H, W) or (H, W, C)
    depth : int
        Bit depth of integer samples (8 or 16), or 0 for floats.

    Raises
    ------
    ValueError
        Missing, unreadable or unsupported file.
    """
    path = Path(path)
    check_suffix(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")

    def check(shape: tuple[int, ...]) -> None:
        if len(shape) in (2, 3):
            try:
                check_encodable(*shape[:2], shape[2] if len(shape) == 3 else 1, max_memory)
            except ValueError as err:
                raise ValueError(f"{path}: {err}") from None

    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            array = np.load(path, mmap_mode="r", allow_pickle=False)  # the header: no sample read yet
        except (OSError, ValueError, EOFError) as err:
            raise ValueError(f"{path}: not a readable .npy file ({err})") from None
        if not np.issubdtype(array.dtype, np.number) or np.iscomplexobj(array):
            raise ValueError(f"{path}: expected a real numeric array, got dtype {array.dtype}")
        check(array.shape)
        try:
            array, depth = integer_samples(array, kind)
        except ValueError as err:
            raise ValueError(f"{path}: {err}") from None
        return array.astype(np.float64), depth
    if suffix == ".exr":
        check(exr_shape(path))
        return read_exr(path).astype(np.float64), 0
    if suffix in (".tif", ".tiff"):
        pixels, depth = read_tiff(path, check)
        return (from_samples(pixels, kind, depth) if depth else pixels.astype(np.float64)), depth
    import imagecodecs

    data = path.read_bytes()
    check(png_shape(data, path))
    try:
        with held_stderr():  # libpng's warnings about a file it then fails to read: not news
            pixels = imagecodecs.png_decode(data)
    except Exception as err:  # imagecodecs raises its own error types for bad data
        raise ValueError(f"{path}: not a readable PNG file ({err})") from None
    if pixels.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"{path}: unsupported PNG sample type {pixels.dtype}")
    depth = 8 if pixels.dtype == np.uint8 else 16
    if pixels.ndim == 3 and pixels.shape[2] in (2, 4):
        warnings.warn(f"{path}: alpha channel dropped", stacklevel=2)
        pixels = pixels[..., :-1]
    if pixels.ndim == 3 and pixels.shape[2] == 1:
        pixels = pixels[..., 0]
    return from_samples(pixels, kind, depth), depth


def image_shape(path: str | os.PathLike) -> tuple[int, int, int]:
    """Height, width and channels that an image file's header announces, no sample read;
    ``ValueError`` for an unreadable or unsupported file."""
    path = Path(path)
    check_suffix(path)
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            shape = np.load(path, mmap_mode="r", allow_pickle=False).shape
        except (OSError, ValueError, EOFError) as err:
            raise ValueError(f"{path}: not a readable .npy file ({err})") from None
    elif suffix == ".exr":
        shape = exr_shape(path)
    elif suffix in (".tif", ".tiff"):
        import tifffile

        try:
            with tifffile.TiffFile(path) as tif:
                shape = tiff_shape(tif.series[0])
        except Exception as err:  # tifffile raises TiffFileError and others for bad data
            raise ValueError(f"{path}: not a readable TIFF file ({err})") from None
    else:
        with open(path, "rb") as f:
            shape = png_shape(f.read(26), path)
    if len(shape) not in (2, 3):
        raise ValueError(f"{path}: not an image (shape {shape})")
    return (*shape[:2], shape[2] if len(shape) == 3 else 1)


#: Channels of each PNG colour type (a palette decodes to RGB or RGBA, counted as RGB).
_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 1, 6: 3}


def png_shape(data: bytes, path: str | os.PathLike) -> tuple[int, int, int]:
    """Height, width and channels (alpha dropped) a PNG file's header announces."""
    if len(data) < 26 or data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR":
        raise ValueError(f"{path}: not a readable PNG file (no PNG header)")
    width, height, depth, colour = struct.unpack_from(">IIBB", data, 16)
    if colour not in _PNG_CHANNELS or depth not in (1, 2, 4, 8, 16):
        raise ValueError(f"{path}: not a readable PNG file (bit depth {depth}, colour type {colour})")
    if width == 0 or height == 0:
        raise ValueError(f"{path}: not a readable PNG file (an image of {width} x {height} pixels)")
    return height, width, _PNG_CHANNELS[colour]


def write_atomic(path: str | os.PathLike, data: bytes | Callable[[str], None]) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename
    (``data`` may be a function that writes a file at the path it is given)."""
    path = Path(path)
    try:
        fd, tmp = tempfiles.make(path)  # named as ours; those left by a killed run are removed
    except OSError as err:  # named after the output, not the temporary file
        raise OSError(err.errno, err.strerror, str(path)) from None
    try:
        with os.fdopen(fd, "wb") as f:
            if not callable(data):
                f.write(data)
        if callable(data):
            data(tmp)
        # mkstemp makes the file private; give it the permissions a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException as err:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(err, OSError) and err.filename == tmp:
            raise OSError(err.errno, err.strerror, str(path)) from None
        raise


def write_array(path: str | os.PathLike, array: np.ndarray, kind: str, depth: int) -> None:
    """Write a decoded array as .npy (float32), EXR (float32), PNG (``depth`` bits, 16 for float
    sources) or TIFF (``depth`` bits, float32 for float sources).

    PNG has no two-channel colour layout: a normal map of ``x, y`` is written as RGB with the
    rebuilt ``z`` in blue.
    """
    path = Path(path)
    check_suffix(path, "output")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        buffer = io.BytesIO()
        np.save(buffer, array.astype(np.float32))
        write_atomic(path, buffer.getvalue())
    elif suffix == ".exr":
        write_atomic(path, lambda tmp: write_exr(tmp, array))
    elif suffix in (".tif", ".tiff"):
        write_atomic(path, write_tiff(to_samples(array, kind, depth) if depth else array.astype(np.float32)))
    else:
        import imagecodecs

        if kind == Kind.NORMAL_MAP and array.ndim == 3 and array.shape[2] == 2:
            from ..transform.normals import with_z

            array = with_z(array)
        write_atomic(path, imagecodecs.png_encode(to_samples(array, kind, depth or 16)))
