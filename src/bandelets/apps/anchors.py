"""External codecs to measure bandelets against: JPEG2000, AVIF and JPEG XL via imagecodecs.

Each anchor codes integer samples, so an array is first mapped from its value range
(``[-1, 1]`` for a normal map, the file's ``[0, 1]`` for a PNG image, the array's own
``[min, max]`` for floats) to integers and decoded back to the same range. The bit depth
follows the source: 8 bits for an 8-bit PNG, otherwise the deepest the codec takes (16 for
JPEG2000 and JPEG XL, 12 for AVIF). The value range is given to the decoder for free.

* ``jpeg2000``: OpenJPEG, irreversible 9/7 wavelet, raw codestream (.j2k); the RGB colour
  transform only for images (the channels of a normal map or geometry image are vectors).
  Quality knob: the target PSNR of OpenJPEG's fixed-quality allocation.
* ``avif``: libavif (AV1 intra), 4:4:4, monochrome (4:0:0) for one channel, no colour
  transform for vectors (identity matrix: +1.5 to +2 dB over YCbCr on the crease map),
  encoder speed 2 (+0.4 to +1.5 dB over speed 4 there). Quality knob: 0 to 100 (integer).
* ``jpegxl``: libjxl, effort 9. Quality knob: the butteraugli distance (lower is better).

:func:`encode` hits a target size by bisection on the knob: the largest file not above it.
:func:`encode_lossless` codes integer samples exactly, at each codec's strongest setting:
OpenJPEG's reversible 5/3 wavelet, libavif level 100 (lossless: 4:4:4, identity matrix), libjxl
lossless at effort 9 (``cjxl -d 0 -e 9``).
"""

from __future__ import annotations

import numpy as np

from ..format.fields import Kind
from ..transform.normals import unit_vectors

__all__ = [
    "ANCHORS",
    "AVIF_SETTINGS",
    "EXTENSIONS",
    "available",
    "decode",
    "encode",
    "encode_lossless",
    "sample_depth",
    "value_range",
    "versions",
]

#: Names of the external codecs, in the order tables list them.
ANCHORS = ("jpeg2000", "avif", "jpegxl")

#: File extension of each codec's files.
EXTENSIONS = {"jpeg2000": "j2k", "avif": "avif", "jpegxl": "jxl"}

_AVIF_SPEED = 2
#: AVIF's settings whose envelope is "AVIF at its strongest" on a normal map (issue 37): the
#: identity matrix at speed 2 (:func:`encode`'s default) and YCbCr at speed 4, each best on some maps.
AVIF_SETTINGS = (("identity", 2), ("ycbcr", 4))
_JXL_EFFORT = 9
_ITERATIONS = 24


def available(codec: str) -> bool:
    """Whether the installed imagecodecs can encode and decode ``codec``."""
    import imagecodecs

    return getattr(imagecodecs, _library(codec)).available


def versions() -> dict[str, str]:
    """Library versions of the available anchors, e.g. ``{"jpeg2000": "openjpeg 2.5.4", ...}``."""
    import imagecodecs

    calls = {"jpeg2000": "jpeg2k_version", "avif": "avif_version", "jpegxl": "jpegxl_version"}
    return {
        c: f"{getattr(imagecodecs, calls[c])()} (imagecodecs {imagecodecs.__version__})"
        for c in ANCHORS
        if available(c)
    }


def _library(codec: str) -> str:
    if codec not in ANCHORS:
        raise ValueError(f"unknown external codec {codec!r}; choose one of {', '.join(ANCHORS)}")
    return {"jpeg2000": "JPEG2K", "avif": "AVIF", "jpegxl": "JPEGXL"}[codec]


def sample_depth(codec: str, source_depth: int) -> int:
    """Bits per sample ``codec`` is given for a source of ``source_depth`` bits (0: float)."""
    if source_depth == 8:
        return 8
    return 12 if codec == "avif" else 16


def value_range(array: np.ndarray, kind: str, source_depth: int) -> tuple[float, float]:
    """The interval mapped to the integer samples (see the module notes)."""
    if kind == Kind.NORMAL_MAP:
        return -1.0, 1.0
    if source_depth:
        return 0.0, 1.0
    low, high = float(np.min(array)), float(np.max(array))
    return low, high if high > low else low + 1.0


def _to_samples(array: np.ndarray, low: float, high: float, bits: int) -> np.ndarray:
    top = 2**bits - 1
    values = np.rint((np.asarray(array, np.float64) - low) / (high - low) * top)
    return np.ascontiguousarray(np.clip(values, 0, top).astype(np.uint8 if bits == 8 else np.uint16))


def _from_samples(samples: np.ndarray, low: float, high: float, bits: int) -> np.ndarray:
    return low + samples.astype(np.float64) / (2**bits - 1) * (high - low)


def _encode_once(
    codec: str, samples: np.ndarray, bits: int, quality: float, vectors: bool, avif: tuple[str, int]
) -> bytes:
    import imagecodecs

    colour = samples.ndim == 3 and samples.shape[2] >= 3
    if codec == "jpeg2000":
        return imagecodecs.jpeg2k_encode(
            samples, level=quality, codecformat="J2K", reversible=False, mct=colour and not vectors
        )
    if codec == "avif":  # imagecodecs codes 1-channel input losslessly: give it 3 and keep Y
        formats = imagecodecs.AVIF.PIXEL_FORMAT
        identity = colour and vectors and avif[0] == "identity"
        return imagecodecs.avif_encode(
            samples if colour else np.ascontiguousarray(np.repeat(samples[..., None], 3, axis=-1)),
            level=int(quality),
            speed=avif[1],
            bitspersample=bits,
            pixelformat=formats.YUV444 if colour else formats.YUV400,
            matrix=imagecodecs.AVIF.MATRIX_COEFFICIENTS.IDENTITY if identity else None,
        )
    return imagecodecs.jpegxl_encode(samples, distance=float(np.exp(-quality)), effort=_JXL_EFFORT)


def encode_lossless(samples: np.ndarray, codec: str) -> bytes:
    """``samples`` (``uint8`` / ``uint16``, (H, W) or (H, W, C)) coded losslessly by ``codec``
    (see the module notes); ``RuntimeError`` if the file does not decode to them exactly."""
    import imagecodecs

    _library(codec)
    samples = np.ascontiguousarray(samples)
    if codec == "jpeg2000":
        data = imagecodecs.jpeg2k_encode(samples, level=0, codecformat="J2K", reversible=True, mct=False)
    elif codec == "avif":
        colour = samples.ndim == 3 and samples.shape[2] >= 3
        data = imagecodecs.avif_encode(
            samples,
            level=100,
            speed=_AVIF_SPEED,
            matrix=imagecodecs.AVIF.MATRIX_COEFFICIENTS.IDENTITY if colour else None,
        )
    else:
        data = imagecodecs.jpegxl_encode(samples, lossless=True, effort=_JXL_EFFORT)
    decoders = {"jpeg2000": imagecodecs.jpeg2k_decode, "avif": imagecodecs.avif_decode}
    if not np.array_equal(decoders.get(codec, imagecodecs.jpegxl_decode)(data), samples):
        raise RuntimeError(f"{codec}'s lossless file does not decode to its samples")
    return data


#: Range of each codec's quality knob (larger is better) and whether it is an integer:
#: OpenJPEG's target PSNR, AVIF's level, minus the log of JPEG XL's distance (25 to 0.05).
_KNOBS = {
    "jpeg2000": (10.0, 140.0, False),
    "avif": (0, 100, True),
    "jpegxl": (-np.log(25.0), -np.log(0.05), False),
}


def encode(
    array: np.ndarray,
    bpp: float,
    codec: str,
    kind: str = "image",
    source_depth: int = 0,
    avif: tuple[str, int] = ("identity", _AVIF_SPEED),
) -> bytes:
    """Encode ``array`` with an external codec into at most ``bpp`` bits per pixel.

    Bisection on the codec's quality knob finds the best quality whose file is not larger
    than the target; it stops early once a file lands within 3 % below the target.

    Parameters
    ----------
    array : ndarray, shape (H, W) or (H, W, C), C in (1, 3, 4)
    bpp : float
        Target rate: ``8 * bytes / (H * W)``.
    codec : {"jpeg2000", "avif", "jpegxl"}
    kind : {"image", "normal-map", "geometry-image"}
    source_depth : {0, 8, 16}
        Bit depth of the PNG the array came from (0: float).
    avif : tuple of (str, int)
        AVIF only: the colour matrix of vectors (``"identity"``, or ``"ycbcr"``: libavif's default)
        and the encoder speed; one of :data:`AVIF_SETTINGS`.

    Returns
    -------
    bytes
        The whole file.

    Raises
    ------
    ValueError
        Unknown or unavailable codec, or even the lowest quality exceeds the target.
    """
    if not available(codec):
        raise ValueError(f"imagecodecs was built without {codec}")
    bits = sample_depth(codec, source_depth)
    samples = _to_samples(array, *value_range(array, kind, source_depth), bits)
    target = bpp * array.shape[0] * array.shape[1] / 8
    low, high, integer = _KNOBS[codec]
    if integer:  # both ends excluded below, so that every level can be tried
        low, high = low - 1, high + 1
    best = b""
    for _ in range(_ITERATIONS):
        if integer and high - low <= 1:
            break
        quality = (low + high) // 2 if integer else (low + high) / 2
        data = _encode_once(codec, samples, bits, quality, kind != Kind.IMAGE, avif)
        if len(data) <= target:
            best = max(best, data, key=len)
            low = quality
            if len(data) >= 0.97 * target:
                break
        else:
            high = quality
    if not best:
        raise ValueError(f"{codec} cannot reach {bpp:g} bpp on this input")
    return best


def decode(
    data: bytes, codec: str, source: np.ndarray, kind: str = "image", source_depth: int = 0
) -> np.ndarray:
    """Decode an anchor's file back to floats in the value range of ``source``.

    ``source`` stands for the side information the decoder is given for free: its shape
    and value range (see :func:`value_range`). A normal map is renormalised to unit
    vectors, as the bandelet decoder does.
    """
    import imagecodecs

    decoders = {"jpeg2000": imagecodecs.jpeg2k_decode, "avif": imagecodecs.avif_decode}
    samples = decoders.get(codec, imagecodecs.jpegxl_decode)(data)
    out = _from_samples(samples, *value_range(source, kind, source_depth), sample_depth(codec, source_depth))
    out = out.reshape(np.shape(source))
    return unit_vectors(out) if kind == Kind.NORMAL_MAP else out
