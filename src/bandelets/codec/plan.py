"""How an image is coded in one piece, decided from the image alone before any coding: its channels,
its layout, its count of wavelet levels and the choices a normal map allows.

A normal map is read (:func:`bandelets.codec.normalmaps.prepare`), renormalised to unit vectors and
coded as two channels where its normals face one way (azimuthal equidistant coordinates, or ``x, y``
as given), as three in local frames otherwise, glued across its border where it is an octahedral
geometry image (:mod:`bandelets.transform.normals`). Which of those applies is the :class:`Plan`;
:func:`plan_image` makes it, with the arrays it was made from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..format.checks import check_image
from ..format.fields import Kind, Layout
from ..format.header import implied_options
from ..runtime.threads import by_rows
from ..transform import normals
from ..transform.wavelets import max_levels
from .alternatives import TRIAL_PIXELS
from .normalmaps import prepare
from .options import EncodeOptions, geometry_options

__all__ = ["Plan", "plan_image"]


@dataclass(frozen=True)
class Plan:
    """The coding plan of one image (one piece of a tiled image).

    The header fields every file of the image shares; the choices made per threshold (directions,
    count of levels, Riesz pair) are :class:`bandelets.codec.alternatives.Candidate`.
    """

    #: Rows and columns of the image.
    height: int
    width: int
    #: Channels coded: 2 for a normal map coded as two channels, 3 in local frames, else the source's.
    channels: int
    #: Bit depth of the source's samples (0: floats), for decoding to the same file type.
    depth: int
    #: How a normal map's channels are laid out in the source and the decoded array.
    layout: Layout
    #: Wavelet levels of the transform before the count of levels is chosen
    #: (:mod:`bandelets.search.levelchoice`): fewer for a folded or spherical image, whose border
    #: must stay the fold.
    levels: int
    #: The geometry-image fields of the header (local frames, extension, normal weight, mesh
    #: vertices), also those a normal map's three channels imply.
    geometry: dict
    #: A normal map coded as two channels (its normals within ``ONE_WAY`` of +z, or ``x, y`` given).
    two_channels: bool
    #: Two channels of azimuthal equidistant coordinates rather than ``x, y``.
    equidistant: bool
    #: The normals of a closed surface on an octahedral geometry image: restored across the folds.
    folded: bool
    #: The two channels may be coded as their Riesz pair (``riesz=True``, or decided by estimate).
    pairable: bool


def plan_image(array, options: EncodeOptions) -> tuple[Plan, np.ndarray, np.ndarray]:
    """The plan of ``array``, its values as measured (float64 ``(H, W, C)``; unit vectors of a normal
    map) and the channels coded (``(H, W, channels)``).

    Raises
    ------
    ValueError
        An unusable image, or ``riesz=True`` for a map that is not coded as two channels.
    """
    kind, depth, layout = options.kind, options.depth, Layout.XYZ
    if kind == Kind.NORMAL_MAP:
        array, depth, layout = prepare(array, depth, options.xy)
    x = given = check_image(array, kind, options.max_memory)
    if kind == Kind.NORMAL_MAP:
        x = by_rows(normals.unit_vectors, x)  # elementwise: the rows' halves in two threads
    levels = max_levels(x.shape[:2])
    geometry = geometry_options(options, x.shape[:2])
    # A map of normals that face one way is coded as two channels: the azimuthal equidistant
    # coordinates of its vectors, or x, y as given (BC5 sources). Not for box mips: the mean of
    # two such channels is not the mean of the vectors (on the shared cobblestone map, 0.2 to 0.3
    # degrees off the box mip at levels 3 to 6 in equidistant coordinates, 0.3 to 0.8 in x, y).
    two = (
        kind == Kind.NORMAL_MAP
        and not options.box_mips
        and (layout != Layout.XYZ or normals.faces_one_way(x))
    )
    # The normals of a closed surface on an octahedral geometry image (never facing one way).
    folded = kind == Kind.NORMAL_MAP and not two and normals.octahedral(x)
    if options.extension == "spherical" or folded:  # no padding: the fold must stay on the image's border
        while levels > 1 and x.shape[0] % (1 << levels):
            levels -= 1
    coded = (by_rows(normals.equidistant, x) if layout == Layout.XYZ else given[..., :2]) if two else x
    if kind == Kind.NORMAL_MAP:  # three channels: always in local frames
        geometry = implied_options(kind, coded.shape[2])
    if options.riesz and not two:
        raise ValueError(
            "riesz=True needs a normal map coded as two channels (its vectors within "
            f"{np.degrees(normals.ONE_WAY):.0f} degrees of +z, or x, y alone)"
        )
    # The encoder decides by estimate whether the pair pays: not where directions are asked for,
    # nor beyond the size whose second set of coefficients a trial may hold.
    automatic = (
        options.riesz is None
        and options.lifting is not True
        and options.wavelet == "cdf97"
        and x[..., 0].size <= TRIAL_PIXELS
    )
    plan = Plan(
        height=x.shape[0],
        width=x.shape[1],
        channels=coded.shape[2],
        depth=depth,
        layout=layout,
        levels=levels,
        geometry=geometry,
        two_channels=two,
        equidistant=two and layout == Layout.XYZ,
        folded=folded,
        pairable=two and bool(options.riesz or automatic),
    )
    return plan, x, coded
