"""Validation at the door: the options of the encoder, and the checks every input passes before any
work on it.

:class:`EncodeOptions` is built once from the keywords of :func:`bandelets.encode` (or of
:func:`bandelets.surfaces.codec.encode_mesh`), validated on construction, and passed down.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..format.checks import check_options
from ..format.container import MIN_TILE
from ..format.fields import (
    BOX_WAVELETS,
    DEFAULT_NORMAL_WEIGHT,
    DEFAULT_TRANSFORM_1D,
    DEFAULT_WAVELET,
    KINDS,
    MAX_MEMORY,
    MAX_NORMAL_WEIGHT,
    MAX_WORK,
    MIN_NORMAL_WEIGHT,
    WAVELETS,
    Kind,
    Transform1D,
    Wavelet,
)
from ..transform.wavelets import check_extension

__all__ = [
    "AUTO_WAVELET",
    "DEFAULT_EFFORT",
    "FULL_TRIALS_FROM",
    "GEOMETRY_FROM",
    "LOOP_FILTER_FROM",
    "TRIALS_FROM",
    "EncodeOptions",
    "geometry_options",
]

#: The ``wavelet`` that lets the encoder choose, per image and target, among
#: :data:`bandelets.codec.encoder.AUTO_CANDIDATES`.
AUTO_WAVELET = "auto"


#: The encoder's effort, from 1 (fastest) to 9, as ``cjxl -e`` and ``avifenc --speed`` have one: the
#: format does not change with it, only how much the encoder tries.
DEFAULT_EFFORT = 7
#: Effort from which a rate target also tries the alternatives whose estimate is close to paying
#: (directions, a Riesz pair, a second count of levels: :mod:`bandelets.codec.alternatives`): each
#: coded as wavelet files at two thresholds about the target and decoded, the one whose PSNR at the
#: target is highest kept for the rate-control loop. Below it the estimates decide alone.
TRIALS_FROM = 7
#: Effort from which each alternative tried gets a rate-control loop of its own, its whole file
#: restored and measured, and the better file is kept (three loops instead of one on the real maps
#: whose Riesz pair is close to paying: the slowest, and what the default was before issue 36).
FULL_TRIALS_FROM = 8
#: Effort from which the encoder fits a loop filter (:mod:`bandelets.search.filterfit`): the last
#: search the fast efforts drop, for it buys the most per second (0.1 to 0.3 s at 512 x 512 for up to
#: 1.2 dB at 0.25 bpp on the vent decal).
LOOP_FILTER_FROM = 3
#: Effort from which the encoder searches the bandelet geometry of every image (paper steps (3) to
#: (10)). Below it (the fast efforts) an image is coded with the wavelets alone, lifted along
#: directions where they pay (the geometry search and the encodes of its rate-control loop are about
#: half of a 512 x 512 encode), except a normal map the hard-surface guess claims
#: (:mod:`bandelets.codec.hardsurface`): there the bandelets are 4 dB better than the lifted wavelets
#: at 1 bpp on the vent decal, so it keeps them. BENCHMARKS, "The fast efforts".
GEOMETRY_FROM = 5


@dataclass(frozen=True, kw_only=True)
class EncodeOptions:
    """How to encode an image: every choice of :func:`bandelets.encode` but the target.

    Built once from the keywords of :func:`bandelets.encode` (or of
    :func:`bandelets.surfaces.codec.encode_mesh`), validated on construction (``ValueError`` if any
    field is unusable, whatever the image), and passed down. Strings name the choices, as in the
    command line; ``kind`` is made a :class:`~bandelets.format.header.Kind` at the door.

    Attributes
    ----------
    transform : {"bandelet", "wavelet"}
        ``"wavelet"`` forces every square to NULL: the same codec without geometry.
    kind : {"image", "normal-map", "geometry-image"}
        A normal map is renormalised to unit vectors before coding and after decoding.
    wavelet : str
        See :data:`bandelets.format.header.WAVELETS`, or ``"auto"``: encode with each of
        :data:`bandelets.codec.encoder.AUTO_CANDIDATES` and keep the better file (twice the time).
    transform_1d : {"alpert2", "haar"}
        1D transform along the directions.
    depth : {0, 8, 16}
        Bit depth of the PNG the values came from (0: float), recorded for decoding to PNG.
    frames : bool
        Geometry images only (normal maps choose by themselves, see ``array``): code the detail
        coefficients of each level in local frames (normal, tangents) estimated from the decoded
        coarser levels (:mod:`bandelets.transform.frames`).
    normal_weight : float
        With ``frames``: precision given to the normal component over the tangential ones,
        from 1/64 to 64.
    extension : {"symmetric", "spherical"}
        Geometry images only: boundary extension of the wavelet; ``"spherical"`` for an
        octahedral spherical geometry image (square, even side: each edge is glued to itself
        reversed, see :mod:`bandelets.surfaces.octahedral`).
    restore : bool
        Let the decoder restore the image (:mod:`bandelets.restore.restoration`) for as many
        iterations as bring it closest to ``array`` (none if that is best).
        Costs no bits; the encoder and decoder then take longer (about 1.6 ms of CPU per
        iteration for 256 x 256 x 2, 6.5 ms for 512 x 512 x 2).
    loop_filter : bool
        Let the decoder filter the (restored) image with a small filter the encoder fits to
        ``array`` and writes into the file (:mod:`bandelets.restore.loopfilter`), where it pays for its
        bytes (a few dozen). Not in tiled files.
    lifting : bool, optional
        Lift the finest :data:`bandelets.transform.directional.LEVELS` wavelet levels along directions
        chosen per block (:mod:`bandelets.transform.directional`; cdf97, not for a geometry image):
        better files on creases at an angle (+0.66 dB BD on the 256 x 256 crease map, +2.63 dB
        at 512, +0.72 dB on fandisk's normal map) in about the same encoding and decoding time.
        None (the default): on for normal maps with cdf97 where the directions pay
        (:func:`bandelets.transform.directional.pays`; else the file is coded without them), off
        otherwise. True: always (an error where it cannot apply); False: never.
    progress : bool
        A progress line on stderr naming the stage (rate control, restoration search).
    max_memory : int
        Refuse (``ValueError``) an image whose encoding would need more than this many bytes.
    xy : bool
        Normal maps: ``array`` holds ``x, y`` and an unused blue (see :mod:`bandelets.codec.normalmaps`,
        which also says how two channels and integer samples are read).
    max_work : int
        Restore for no more iterations than a decoder's ``max_work`` allows
        (:func:`bandelets.format.limits.check_work`): with the default, the file decodes within the
        default limits of :func:`bandelets.decode`.
    tile : int
        An image with a side above ``tile`` pixels is coded in tiles of about ``tile`` x ``tile``
        (:mod:`bandelets.codec.tiles`: independent tiles at one threshold, two at a time; memory
        bounded whatever the size, a region can be decoded alone), at least
        :data:`~bandelets.codec.tiles.MIN_TILE`. The default, 0, codes in one piece what fits
        ``max_memory`` and in tiles of :data:`~bandelets.codec.tiles.TILE` what does not (tile borders
        can show at low rates: :func:`bandelets.format.limits.tile_side`).
    lossless : bool, optional
        True: code the integer samples of the source exactly (:mod:`bandelets.coding.lossless`; no
        target): ``uint8`` / ``uint16`` samples of a normal map, or values read from 8 or
        16-bit samples with their ``depth`` (``ValueError`` for anything else); the file decodes
        to the same values, every channel given (``xy`` aside). None (the default): under a
        ``bpp`` target, the lossless file when the source has such samples and that file fits
        the target (smaller than asked, and exact). False: never.
    riesz : bool, optional
        Normal maps coded as two channels: code them as their Riesz pair (:mod:`bandelets.transform.riesz`:
        the channel along the gradients of a height and the one across them), which halves what
        a map baked from a height field costs (+1.4 dB BD on the 256 x 256 bevel map, +4.1 on the
        bumps, +0.7 on the acacia door). None (the default): where the estimate says it pays
        (:data:`RIESZ_PAYS_BELOW`), or under a rate target where it nearly does, both files and
        the better kept (:data:`RIESZ_TRIAL_BELOW`), up to :data:`TRIAL_PIXELS` pixels and with
        cdf97. True: always (a Riesz pair is not lifted along directions); False: never.
    box_mips : bool
        Make the image each prefix of the file decodes to (``decode(data, level=k)``, format version
        19) the ``2**k x 2**k`` box mip of the coded map, up to quantization: the wavelet becomes
        one whose analysis low-pass is a box average (:data:`bandelets.format.fields.BOX_WAVELETS`:
        ``rbio1.3`` in place of the default ``cdf97``; ``haar`` kept if given, any other refused) and a
        normal map is coded as its three unit-vector channels (in local frames; no equidistant
        coordinates, Riesz pair or directions, whose mean is not the mean of the vectors), so
        that its level images are the renormalised box averages of its vectors, as a GPU mip chain
        is made. Costs rate (BENCHMARKS, "Box mips from a prefix"; docs/gpu.md).
    effort : int
        How much the encoder tries, from 1 to 9 (default :data:`DEFAULT_EFFORT`): from
        :data:`FULL_TRIALS_FROM` a rate target encodes each alternative close to paying through a
        rate-control loop of its own and keeps the better file; from :data:`TRIALS_FROM` it picks
        among them the one whose wavelet files promise most at the target; below, the estimates
        choose alone; below :data:`GEOMETRY_FROM` no bandelet geometry is searched but on
        hard-surface maps; below :data:`LOOP_FILTER_FROM` no loop filter is fitted either; at 9 a
        normal map in one piece is also coded with Haar along the directions and the directions
        forced, and the better file kept (:mod:`bandelets.codec.variants`, twice the time), and below 9 that
        variant alone where the map's runs of equal samples say so
        (:mod:`bandelets.codec.hardsurface`). The file's format is the same at every effort.
    mesh_vertices : int
        The vertex count of the mesh a geometry image was sampled from, which
        :func:`bandelets.surfaces.codec.encode_mesh` records for its decoder (0: none).

    Examples
    --------
    >>> EncodeOptions(kind="normal-map").wavelet
    'cdf97'
    >>> EncodeOptions(wavelet="db3")
    Traceback (most recent call last):
    ...
    ValueError: unknown wavelet 'db3'; choose one of cdf97, haar, db2, db4, db6, db8, rbio1.3, auto
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
    effort: int = DEFAULT_EFFORT
    box_mips: bool = False

    def __post_init__(self) -> None:
        if self.lossless not in (None, True, False):
            raise ValueError(f"lossless must be None, True or False, got {self.lossless!r}")
        if self.lossless and self.kind == Kind.GEOMETRY_IMAGE:
            raise ValueError("a geometry image has float positions: it has no lossless coding")
        if not (isinstance(self.tile, (int, np.integer)) and (self.tile == 0 or self.tile >= MIN_TILE)):
            raise ValueError(
                f"tile must be 0 (automatic) or an integer of at least {MIN_TILE}, got {self.tile!r}"
            )
        if self.kind not in KINDS:
            raise ValueError(f"unknown kind {self.kind!r}; choose one of {', '.join(KINDS)}")
        object.__setattr__(self, "kind", Kind(self.kind))  # the string turned into its type once, here
        if self.xy and self.kind != Kind.NORMAL_MAP:
            raise ValueError("xy applies to normal maps only")
        if not (isinstance(self.effort, (int, np.integer)) and 1 <= self.effort <= 9):
            raise ValueError(f"effort must be a whole number from 1 to 9, got {self.effort!r}")
        if self.riesz not in (None, True, False):
            raise ValueError(f"riesz must be None, True or False, got {self.riesz!r}")
        if self.riesz and self.kind != Kind.NORMAL_MAP:
            raise ValueError("riesz applies to normal maps only (their two channels)")
        if self.riesz and self.lifting:
            raise ValueError("a Riesz pair is not lifted along directions: give riesz or lifting, not both")
        if self.depth not in (0, 8, 16):
            raise ValueError(f"depth must be 0, 8 or 16, got {self.depth}")
        check_options(self.transform, self.wavelet, self.transform_1d, wavelets=(*WAVELETS, AUTO_WAVELET))
        if self.box_mips:
            self._box_wavelet()
        if self.lifting and (self.wavelet not in ("cdf97", AUTO_WAVELET) or self.kind == Kind.GEOMETRY_IMAGE):
            raise ValueError(
                f"directional lifting needs the cdf97 wavelet and an image or a normal map, got "
                f"{self.wavelet} and a {self.kind}"
            )
        if self.kind != Kind.GEOMETRY_IMAGE:
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

    def _box_wavelet(self) -> None:
        """With ``box_mips``: the wavelet made a box one, or ``ValueError`` for what cannot have box mips."""
        if self.wavelet == DEFAULT_WAVELET:
            object.__setattr__(self, "wavelet", BOX_WAVELETS[0])
        if self.wavelet not in BOX_WAVELETS:
            raise ValueError(
                f"box_mips needs a wavelet whose analysis low-pass is a box ({', '.join(BOX_WAVELETS)}), "
                f"got {self.wavelet}"
            )
        if self.riesz or self.lifting or self.extension != "symmetric":
            raise ValueError("box_mips codes no Riesz pair, no directions and no spherical extension")


def geometry_options(options: EncodeOptions, shape: tuple[int, int]) -> dict:
    """The geometry-image fields of the header (``{}`` for other kinds); ``ValueError`` if an
    image of ``shape`` cannot have the options' extension."""
    if options.kind != Kind.GEOMETRY_IMAGE:
        return {}
    check_extension(shape, options.wavelet, 1, options.extension)  # the encoder then picks levels that fit
    weight = float(options.normal_weight) if options.frames else 1.0
    return {
        "extension": options.extension,
        "frames": bool(options.frames),
        "normal_weight": weight,
        "mesh_vertices": int(options.mesh_vertices),
    }
