"""The fields of a .bdl file and what they may hold: the codes written to disk for each choice,
the choices as types (:class:`Kind`, :class:`Layout`), the bounds of every field and the limits a
decoder enforces by default.

The codes are the format: never renumber one, only add new names (and say so in
:data:`FORMAT_VERSION`). The algorithms take their names from here. This module imports nothing.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Literal

__all__ = [
    "BOX_WAVELETS",
    "DEFAULT_NORMAL_WEIGHT",
    "DEFAULT_TRANSFORM_1D",
    "DEFAULT_WAVELET",
    "DEPTH_CODES",
    "EXTENSIONS",
    "EXTENSION_CODES",
    "FORMAT_VERSION",
    "KINDS",
    "KIND_CODES",
    "LAYOUTS",
    "LAYOUT_CODES",
    "LOSSLESS",
    "MAGIC",
    "MAX_FILTER_CLIP",
    "MAX_FILTER_CROSS",
    "MAX_FILTER_RADIUS",
    "MAX_FILTER_SHIFT",
    "MAX_FILTER_WIDTH",
    "MAX_LEVELS",
    "MAX_LIFTING",
    "MAX_MEMORY",
    "MAX_NORMAL_WEIGHT",
    "MAX_RESTORATION",
    "MAX_SAMPLES",
    "MAX_SIDE",
    "MAX_THRESHOLD",
    "MAX_WORK",
    "MIN_NORMAL_WEIGHT",
    "MIN_THRESHOLD",
    "NORMAL_MAP_WEIGHT",
    "TILED_CODE",
    "TRANSFORMS",
    "TRANSFORMS_1D",
    "TRANSFORM_1D_CODES",
    "TRANSFORM_CODES",
    "WAVELETS",
    "WAVELET_CODES",
    "FormatError",
    "Kind",
    "Layout",
    "Transform1D",
    "Wavelet",
    "padded_shape",
]

#: The first bytes of every .bdl file.
MAGIC = b"BDL\x1a"
#: The version this build writes and reads (``docs/history.md``: what each version changed).
FORMAT_VERSION = 19
#: The byte where a file of one tile has its kind, in a tiled file (:mod:`bandelets.format.container`).
TILED_CODE = 255


class Kind(StrEnum):
    """What a file's values are (its kind field); the API and the command line take the strings."""

    #: Any image: values as they are.
    IMAGE = "image"
    #: Unit normals, renormalised before coding and after decoding (:mod:`bandelets.codec.normalmaps`).
    NORMAL_MAP = "normal-map"
    #: Positions of a surface sampled on a grid (:mod:`bandelets.surfaces`).
    GEOMETRY_IMAGE = "geometry-image"


class Layout(StrEnum):
    """How a normal map's channels are laid out in the source and in the decoded array."""

    #: Three channels ``x, y, z``.
    XYZ = "xyz"
    #: Two channels ``x, y`` (a BC5-style map), or three whose third is no normal component.
    XY = "xy"
    #: Red and green of an image hold ``x, y``.
    RG = "rg"


# The code written to disk for each choice. The codes are the format: never renumber one, only
# add new names (and say so in FORMAT_VERSION). The algorithms take their names from here.
KIND_CODES = {Kind.IMAGE: 0, Kind.NORMAL_MAP: 1, Kind.GEOMETRY_IMAGE: 2}
TRANSFORM_CODES = {"bandelet": 0, "wavelet": 1, "lossless": 2}
#: The transform of a lossless file (:mod:`bandelets.coding.lossless`): not a choice of the lossy coder.
LOSSLESS = "lossless"
#: Wavelets (:mod:`bandelets.transform.wavelets`). ``rbio1.3`` added within version 19 (a decoder that
#: predates it refuses such a file by its unknown wavelet code).
WAVELET_CODES = {"cdf97": 0, "haar": 1, "db2": 2, "db4": 3, "db6": 4, "db8": 5, "rbio1.3": 6}
#: 1D transforms along the directions (:mod:`bandelets.transform.bandeletize`).
TRANSFORM_1D_CODES = {"haar": 0, "alpert2": 1}
#: Boundary extensions of ``cdf97`` (geometry images only).
EXTENSION_CODES = {"symmetric": 0, "spherical": 1}
#: Layouts of a normal map's source (:class:`Layout`): ``xy`` and ``rg`` are coded as two channels.
LAYOUT_CODES = {Layout.XYZ: 0, Layout.XY: 1, Layout.RG: 2}
#: Sample depths of the source (0: float), for decoding back to them.
DEPTH_CODES = {0: 0, 8: 1, 16: 2}
KINDS, WAVELETS, TRANSFORMS_1D, EXTENSIONS, LAYOUTS = map(
    tuple, (KIND_CODES, WAVELET_CODES, TRANSFORM_1D_CODES, EXTENSION_CODES, LAYOUT_CODES)
)
#: The transforms of the lossy coder (``encode(transform=...)``).
TRANSFORMS = tuple(t for t in TRANSFORM_CODES if t != LOSSLESS)
# The same names as types, for signatures (tests/test_bitstream.py checks they agree).
Wavelet = Literal["cdf97", "haar", "db2", "db4", "db6", "db8", "rbio1.3"]
Transform1D = Literal["haar", "alpert2"]
#: The encoder's defaults (:class:`bandelets.codec.options.EncodeOptions`): the wavelet, the 1D transform,
#: and the weight of the normal component of a geometry image in local frames.
DEFAULT_WAVELET = "cdf97"
#: The wavelets whose analysis low-pass is the box average of a pair: the approximation of ``k`` levels
#: is the ``2**k x 2**k`` box average of the channel, a mip (``encode(box_mips=True)``, issue 39).
BOX_WAVELETS = ("rbio1.3", "haar")
DEFAULT_TRANSFORM_1D = "alpert2"
DEFAULT_NORMAL_WEIGHT = 2.0
#: Most wavelet decomposition levels a file may have.
MAX_LEVELS = 6
#: Most wavelet levels a file may lift along directions (:mod:`bandelets.transform.directional`).
MAX_LIFTING = 3
#: Most restoration iterations a file may ask for (one byte; :mod:`bandelets.restore.restoration`).
MAX_RESTORATION = 100
#: Bounds of the loop filter (:class:`bandelets.format.filter.LoopFilter`): at most 24 + 2 x 12 taps per
#: channel.
MAX_FILTER_RADIUS, MAX_FILTER_CROSS, MAX_FILTER_SHIFT, MAX_FILTER_WIDTH, MAX_FILTER_CLIP = 3, 2, 24, 24, 16
#: Weight of the normal component of the details of a normal map of three channels, coded in
#: local frames (implied by the kind and the channel count: no header field; chosen in
#: :mod:`bandelets.transform.frames`).
NORMAL_MAP_WEIGHT = 0.35
#: Largest side and sample count a decoder accepts by default.
MAX_SIDE = 16384
MAX_SAMPLES = 2**28
#: Largest working set, in bytes, the decoder (and the encoder) accepts by default
#: (:mod:`bandelets.format.limits`).
MAX_MEMORY = 2 * 2**30
#: Most restoration work the decoder (and the encoder) accepts by default
#: (:func:`bandelets.format.limits.restoration_work`): all 100 iterations up to 1024 x 1024 x 2 samples,
#: 31 at 2048 x 2048 x 2. The slowest file it lets through took 17.5 s of CPU time
#: (``benchmarks/worst_decode.py``, 2048 x 2048 x 1 restored 63 times, 65 ns per sample and
#: iteration; 1024 x 1024 x 1 restored 100 times: 5.2 s).
MAX_WORK = 2**28
#: Range of the threshold a file may hold: powers of two within the normal float32 numbers (the
#: threshold is a float32 on disk), so the restoration's smoothing, ``(0.01 T)**2``, stays a
#: normal float64, the squares of the largest values (``2**30 T``) stay finite, and no image in
#: any unit needs a finer or a coarser step (about 7.5e-37 to 1.3e36).
MIN_THRESHOLD, MAX_THRESHOLD = 2.0**-120, 2.0**120
#: Range of the normal weight a file may hold.
MIN_NORMAL_WEIGHT, MAX_NORMAL_WEIGHT = 1 / 64, 64.0


class FormatError(ValueError):
    """A .bdl file is corrupt, truncated, hostile or of an unsupported version."""


def padded_shape(shape: tuple[int, int], levels: int) -> tuple[int, int]:
    """Size of a channel once padded to a multiple of ``2**levels`` on both sides."""
    step = 1 << levels
    return tuple(-(-side // step) * step for side in shape)
