"""Reading and writing the arrays the command line works on: PNG and .npy.

PNG samples are mapped to [0, 1] for images and to [-1, 1] for normal maps (``2 v - 1``),
and mapped back the same way, at the bit depth recorded in the .bdl file. PNG coding goes
through ``imagecodecs`` (libpng), which reads and writes 16-bit RGB.
"""

from __future__ import annotations

import io
import os
import struct
import tempfile
import warnings
from pathlib import Path

import numpy as np

from .memory import MAX_MEMORY, check_encodable

__all__ = ["read_array", "write_array", "write_atomic"]


def read_array(path: str | os.PathLike, kind: str, max_memory: int = MAX_MEMORY) -> tuple[np.ndarray, int]:
    """Read a PNG or .npy file.

    An image the encoder would refuse (:func:`bandelets.memory.check_encodable` with
    ``max_memory``) is refused from its header, before its samples are decoded: a few hundred
    kilobytes of PNG can hold gigabytes of samples.

    Returns
    -------
    array : ndarray, float64, (H, W) or (H, W, C)
    depth : int
        PNG bit depth (8 or 16), or 0 for .npy.

    Raises
    ------
    ValueError
        Missing, unreadable or unsupported file.
    """
    path = Path(path)
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
        return np.array(array, dtype=np.float64), 0
    if suffix != ".png":
        raise ValueError(f"{path}: unsupported input format {suffix or '(none)'}; use .png or .npy")
    import imagecodecs

    data = path.read_bytes()
    check(_png_shape(data, path))
    try:
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
    values = pixels.astype(np.float64) / (2**depth - 1)
    if kind == "normal-map":
        values = 2.0 * values - 1.0
    return values, depth


#: Channels of each PNG colour type (a palette decodes to RGB or RGBA, counted as RGB).
_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 1, 6: 3}


def _png_shape(data: bytes, path: Path) -> tuple[int, int, int]:
    """Height, width and channels (alpha dropped) a PNG file's header announces."""
    if len(data) < 26 or data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR":
        raise ValueError(f"{path}: not a readable PNG file (no PNG header)")
    width, height, depth, colour = struct.unpack_from(">IIBB", data, 16)
    if colour not in _PNG_CHANNELS or depth not in (1, 2, 4, 8, 16):
        raise ValueError(f"{path}: not a readable PNG file (bit depth {depth}, colour type {colour})")
    return height, width, _PNG_CHANNELS[colour]


def write_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent or ".")
    except OSError as err:  # named after the output, not the temporary file
        raise OSError(err.errno, err.strerror, str(path)) from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
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
    """Write a decoded array as .npy (float32) or PNG (``depth`` bits, 16 for float sources)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npy":
        buffer = io.BytesIO()
        np.save(buffer, array.astype(np.float32))
        write_atomic(path, buffer.getvalue())
        return
    if suffix != ".png":
        raise ValueError(f"{path}: unsupported output format {suffix or '(none)'}; use .png or .npy")
    import imagecodecs

    values = (array + 1.0) / 2.0 if kind == "normal-map" else array
    depth = depth or 16
    top = 2**depth - 1
    pixels = np.clip(np.rint(values * top), 0, top).astype(np.uint8 if depth == 8 else np.uint16)
    write_atomic(path, imagecodecs.png_encode(pixels))
