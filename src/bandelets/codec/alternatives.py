"""The other ways a normal map may be coded, and the estimates that choose among them: the finest
levels lifted along directions (:mod:`bandelets.transform.directional`), another count of wavelet
levels (:mod:`bandelets.search.levelchoice`) and the Riesz pair of two channels
(:mod:`bandelets.transform.riesz`).

Each is chosen from a cost estimate at one threshold; where the estimate is close, a rate target
encodes both files and keeps the better (:class:`Candidate`, tried by :mod:`bandelets.codec.piece`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..format.fields import MAX_THRESHOLD, Kind
from ..search import directions, sampled
from ..search.levelchoice import choose_levels
from ..transform import riesz
from ..transform.bandelets import padded_channels, wavelet_coefficients
from ..transform.directional import LEVELS
from ..transform.wavelets import max_levels, wavedec
from .options import EncodeOptions

__all__ = [
    "RIESZ_PAYS_BELOW",
    "RIESZ_SIGN_BY_COST",
    "RIESZ_TRIAL_BELOW",
    "TRIAL_BELOW",
    "TRIAL_PIXELS",
    "Candidate",
    "lifted",
    "lifting_levels_for",
    "raised_t_max",
    "riesz_pair",
    "with_levels",
]


@dataclass
class Candidate:
    """A way to code the channels: what one rate-control search encodes at every threshold it tries."""

    #: The (padded) transformed channels, one array per channel, Mallat layout.
    coefficients: list
    #: Wavelet levels of the transform.
    levels: int
    #: Finest levels lifted along directions (0: none), and their direction fields (None: none).
    lifting_levels: int = 0
    lifting: list | None = None
    #: The sign of the Riesz pair coded (:func:`bandelets.transform.riesz.forward`), 0: the channels.
    turn: int = 0


#: Where :func:`bandelets.search.directions.pays` says the directions do not pay but their cost ratio
#: (:func:`bandelets.search.directions.cost_ratio`) is below this, a rate target tries both files and
#: keeps the better: the estimate's threshold is a compromise that the objects' normal maps
#: rendered from meshes cross (ratios of 0.89 to 0.95 at 256 and 512, where the lifted file
#: gains 0.1 to 2.6 dB; the crease map at 256 and low rates, 0.89 to 0.91, loses 0.1 to 0.4 dB).
#: The smooth maps (bumps, lava flow: 1.00 to 1.01) are not tried.
TRIAL_BELOW = 0.96


#: Largest image (pixels) tried both ways: the trial holds a second set of coefficients.
TRIAL_PIXELS = 1024 * 1024


def lifted(
    coded: np.ndarray, plain: list, levels: int, lifting_levels: int, threshold: float, check: bool
) -> tuple[list, list | None, int, tuple | None]:
    """The coefficients of the (padded) channels of ``coded`` lifted along directions, the
    directions, chosen for ``threshold`` (:func:`bandelets.search.directions.lift`: slopes and pair
    codes), the levels lifted and None; or, with ``check``, where the directions do not pay
    (:func:`bandelets.search.directions.pays`), the plain coefficients ``plain``, None, 0 and, when
    their cost ratio is below :data:`TRIAL_BELOW`, the lifted ones, directions and levels (to try).
    Above :data:`bandelets.search.sampled.SAMPLED_ABOVE` pixels, decided on a sample
    (:func:`bandelets.search.sampled.lifted`: no trial)."""
    channels = padded_channels(coded, levels)
    if sampled.applies(coded.shape[:2]):  # a large image: the choices made on a sample of it
        return sampled.lifted(channels, plain, levels, lifting_levels, threshold, check, len(channels) == 3)
    lifted, fields, lifting_levels, cost = directions.lift(channels, levels, lifting_levels, threshold)
    frames = len(channels) == 3  # a normal map's three channels are coded in local frames
    if not check:
        return lifted, fields, lifting_levels, None
    # One ratio for both questions (the plain coefficients' cost is a synthesis of the image).
    ratio = directions.cost_ratio(channels, lifted, fields, levels, lifting_levels, threshold, plain, cost)
    if directions.ratio_pays(ratio, frames):
        return lifted, fields, lifting_levels, None
    return plain, None, 0, (lifted, fields, lifting_levels) if ratio < TRIAL_BELOW else None


def with_levels(
    coded: np.ndarray, levels: int, threshold: float | None, options: EncodeOptions, geometry: dict
) -> tuple[list, list | None, int]:
    """The coefficients of the channels ``coded`` with ``levels`` wavelet levels, lifted along
    directions chosen for ``threshold`` where they pay (none without a threshold), the directions
    and the levels lifted: a count of levels to try (:func:`bandelets.search.levelchoice.levels_to_try`)."""
    coefficients = wavelet_coefficients(coded, options.wavelet, levels, options.extension)
    lifting_levels = lifting_levels_for(options, levels, geometry)
    if not lifting_levels or threshold is None:
        return coefficients, None, 0
    return lifted(coded, coefficients, levels, lifting_levels, threshold, options.lifting is None)[:3]


#: Where the Riesz pair's :func:`bandelets.search.directions.cost` over that of the channels (lifted or
#: not) is below this, the pair is coded (:func:`riesz_pair`); where it is below
#: :data:`RIESZ_TRIAL_BELOW`, a rate target encodes both files and keeps the better (else the
#: channels). The estimate misses much of what the context coder makes of a pair: of the files of
#: the maps of issue 15 at 0.25 to 2 bpp (``benchmarks/riesz_choice.py``; BENCHMARKS, "Where main
#: stands: format version 15"), those at a ratio of 0.91 or less gained +0.7 to +4.2 dB with it
#: (bevel, bumps, acacia door) but one (the acacia door at 0.25 bpp: 0.88, -0.14 dB); between 0.93
#: and 1.5 some gained up to 1.8 dB (bevel, bumps, acacia door, crease at 0.25 bpp, 1.50 at 512)
#: and others lost up to 1.7 dB (bunny from the top at 0.35 and 0.5 bpp: 0.99 and 1.08); above 1.5
#: only losses (0.3 to 24 dB: lava flow, fandisk from the top, crease from 1 bpp).
RIESZ_PAYS_BELOW = 0.9


RIESZ_TRIAL_BELOW = 1.6


#: Where the smaller curl (:func:`bandelets.transform.riesz.oriented`) still holds more than this share of the
#: energy, the map is no height field, and the sign of the pair is the one whose cost estimate is
#: lower: on the acacia door (26 % of curl with the smaller-curl sign) the other sign's estimate is
#: lower and its files better by 0.05 to 0.86 dB at 0.5 to 2 bpp (+0.27 dB BD).
RIESZ_SIGN_BY_COST = 0.05


def riesz_pair(
    coded: np.ndarray,
    coefficients: list,
    lifting,
    lifted: int,
    levels: int,
    threshold: float,
    options: EncodeOptions,
    choose: bool,
) -> tuple[int, list, int, float]:
    """The Riesz sign and the pair's coefficients of the channels ``coded``
    (:func:`bandelets.transform.riesz.oriented`,
    padded), its wavelet levels, and the ratio of their :func:`bandelets.search.directions.cost` at
    ``threshold`` over that of the channels' ``coefficients`` (``levels`` levels, ``lifted`` of them
    lifted with the directions ``lifting``, if any); 0 with ``options.riesz``. With ``choose``, the
    pair's levels are chosen again (:func:`bandelets.search.levelchoice.choose_levels`): its coarse band is
    not the channels' (the bevel map at 256 kept 2 levels of 5 for its channels; its pair lost 0.28
    dB at 0.25 bpp with them, gained 0.16 at 2 bpp)."""

    def plain_cost(samples, transformed, count):  # unlifted: the directions' side costs zeros
        return directions.cost(samples, transformed, None, count, min(LEVELS, count), threshold)

    top = max_levels(coded.shape[:2]) if choose else levels
    channels = padded_channels(coded, top)
    sign, *pair = riesz.oriented(*channels)
    turned = [wavedec(c, options.wavelet, top) for c in pair]
    energy = [float(np.sum(c * c)) for c in pair]
    if energy[1] > RIESZ_SIGN_BY_COST * sum(energy):  # no height field: the cheaper sign
        other = riesz.forward(*channels, -sign)
        flipped = [wavedec(c, options.wavelet, top) for c in other]
        if plain_cost(other, flipped, top) < plain_cost(pair, turned, top):
            sign, pair, turned = -sign, other, flipped
        del other, flipped
    if choose and (fewer := choose_levels(turned, top, threshold)) < top:
        top, channels = fewer, padded_channels(coded, fewer)
        pair = riesz.forward(*channels, sign)
        turned = [wavedec(c, options.wavelet, top) for c in pair]
    if options.riesz:
        return sign, turned, top, 0.0
    channels = padded_channels(coded, levels)
    if lifting is None:
        now = plain_cost(channels, coefficients, levels)
    else:
        now = directions.cost(channels, coefficients, lifting, levels, lifted, threshold)
    return sign, turned, top, plain_cost(pair, turned, top) / now if now > 0 else 1.0


def raised_t_max(coefficients: list, t_max: float) -> float:
    """``t_max`` raised to twice the largest of ``coefficients`` (a Riesz pair gathers the energy
    of two channels into one), within :data:`bandelets.format.header.MAX_THRESHOLD`."""
    return min(max(t_max, 2.0 * max(float(np.abs(c).max()) for c in coefficients)), MAX_THRESHOLD)


def lifting_levels_for(options: EncodeOptions, levels: int, geometry: dict) -> int:
    """Wavelet levels to lift along directions for ``options.lifting`` (see :func:`encode`)."""
    if options.lifting is None:  # the default: normal maps with CDF 9/7
        wanted = options.kind == Kind.NORMAL_MAP and options.wavelet == "cdf97"
    else:
        wanted = options.lifting
    return min(LEVELS, levels) if wanted else 0
