"""Unit normals and the coordinates two channels of a normal map are coded in.

A normal map is renormalised to unit vectors before coding and after decoding
(:func:`unit_vectors`, :func:`unit_normals`); an ``x, y`` map gets its ``z`` back as a BC5 decoder
does (:func:`with_z`).

The other maps whose normals face one way (every one within :data:`ONE_WAY` of +z:
tangent-space and height-field maps, object-space maps seen from one side) are coded as two
channels too, but not as ``x, y``: as azimuthal equidistant coordinates (:func:`equidistant`),
the normal's angle to +z along its direction in the plane. ``x = sin(angle)`` flattens the
steep normals: there a tilt moves ``x, y`` little and ``z`` fast, so an error in ``x, y`` grows
by ``1 / z`` on the vector (2.9 times at 70 degrees), and the coder spends its bits where the
normals are flat. The angle itself turns every tilt into the same step, as the error on the
unit vectors measures it, and goes on past the horizon. The gain is largest where the normals
are steep (format version 11; figures in BENCHMARKS, "Equidistant coordinates").

A map of the normals of a closed surface sampled on an octahedral geometry image
(:mod:`bandelets.surfaces`: ``make_geometry_image(mesh).normals``) is glued across its border as
the unfolded octahedron is: pixel ``(0, j)`` neighbours ``(0, n-1-j)`` across the top edge, and
so on along the four edges. Nothing in the array says so, but its border shows it:
:func:`octahedral` finds it, and the file says so (format version 14), so that the decoder's
restoration works across those folds too.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..runtime.threads import CORES, workers

__all__ = [
    "FOLD_EVIDENCE",
    "FOLD_RATIO",
    "ONE_WAY",
    "equidistant",
    "faces_one_way",
    "octahedral",
    "unit_normals",
    "unit_vectors",
    "with_z",
    "as_real",
    "hemisphere",
    "unit_length",
]


def unit_vectors(vectors: np.ndarray) -> np.ndarray:
    """Vectors (last axis) scaled to unit length; zero vectors become +z."""
    # einsum: less than half the time of np.linalg.norm on short vectors.
    norm = np.sqrt(np.einsum("...c,...c->...", vectors, vectors))[..., None]
    out = vectors / np.where(norm > 0, norm, 1.0)
    out[..., 2] = np.where(norm[..., 0] > 0, out[..., 2], 1.0)
    return out


def with_z(xy: np.ndarray) -> np.ndarray:
    """Normals of shape (..., 3) from their ``x, y`` (..., 2), as a BC5 decoder rebuilds them:
    ``z = sqrt(1 - x^2 - y^2)``, 0 where ``x, y`` lie outside the unit disc."""
    z = np.sqrt(np.maximum(1.0 - np.sum(xy * xy, axis=-1, keepdims=True), 0.0))
    return np.concatenate([xy, z], axis=-1)


def unit_normals(
    channels: np.ndarray, height: int, width: int, equidistant: bool = False
) -> np.ndarray | None:
    """``unit_vectors(with_z(xy))`` (two channels) or ``unit_vectors(xyz)`` (three) of the first
    ``height`` rows and ``width`` columns of ``channels``, shape (C, H, W), in one compiled pass
    with the same numbers (what a decoder returns, ten times faster than the two numpy passes).
    With ``equidistant``, two channels are azimuthal equidistant coordinates
    (:func:`bandelets.codec.normalmaps.equidistant`), not ``x, y``.

    Returns
    -------
    ndarray of float64, shape (height, width, 3), or None if a value of ``channels`` is not finite.
    """
    out = np.empty((height, width, 3))
    channels = as_real(channels)
    if CORES == 1 or height * width < THREADED_PIXELS:
        return out if _unit_normals(channels, out, equidistant, 0, height) else None
    # The two halves of the rows in two threads (the kernel releases the GIL).
    second = workers().submit(_unit_normals, channels, out, equidistant, height // 2, height)
    first = _unit_normals(channels, out, equidistant, 0, height // 2)
    return out if second.result() and first else None


def as_real(channels) -> np.ndarray:
    """``channels`` as float32 or float64, without a copy where they are one already: the kernels
    widen float32 restored channels to float64 value by value, the numbers decode makes."""
    channels = np.asarray(channels)
    return channels if channels.dtype in (np.float32, np.float64) else channels.astype(np.float64)


@njit(cache=True, nogil=True, inline="always")
def hemisphere(a, b, equidistant):
    """The normal ``x, y, z`` (not renormalised) that two coded channels stand for: ``x, y`` with
    ``z`` rebuilt (0 outside the unit disc), or azimuthal equidistant coordinates, whose length
    is the angle to +z (at most pi: a longer decoded one stops at -z rather than wrap around)."""
    if not equidistant:
        return a, b, np.sqrt(max(1.0 - (a * a + b * b), 0.0))
    angle = np.sqrt(a * a + b * b)
    # sin(t) / t, by its series where the division loses digits.
    shrink = 1.0 - angle * angle / 6.0 if angle < 1e-4 else np.sin(min(angle, np.pi)) / angle
    return a * shrink, b * shrink, np.cos(min(angle, np.pi))


@njit(cache=True, nogil=True)
def _unit_normals(channels, out, equidistant, first, last):
    """The rows ``first`` to ``last`` of :func:`unit_normals` (each value of ``channels`` widened to
    float64 exactly before any arithmetic); False if one of them is not finite."""
    finite = True
    for i in range(first, last):
        for j in range(out.shape[1]):
            x, y = np.float64(channels[0, i, j]), np.float64(channels[1, i, j])
            if channels.shape[0] > 2:
                z = np.float64(channels[2, i, j])
                finite &= np.isfinite(z)
            else:
                x, y, z = hemisphere(x, y, equidistant)
            finite &= np.isfinite(x) and np.isfinite(y)
            out[i, j, 0], out[i, j, 1], out[i, j, 2] = unit_length(x, y, z)
    return finite


@njit(cache=True, nogil=True, inline="always")
def unit_length(a, b, c):
    """``a, b, c`` scaled to unit length; a zero vector becomes +z (as :func:`unit_vectors`)."""
    norm = np.sqrt(a * a + b * b + c * c)
    if norm > 0:
        return a / norm, b / norm, c / norm
    return a, b, 1.0


#: Pixels from which the encoder's measure of a normal map (:func:`psnr_of_channels`) sums the
#: two halves of the rows in two threads: it measures every restoration iteration, 0.13 s of a
#: 512 x 512 encode in one thread (2-core machine). The decoder's :func:`unit_normals` too.
THREADED_PIXELS = 256 * 256


#: The largest angle to +z of a map coded as two channels of equidistant coordinates, radians.
#: Towards -z those coordinates stretch (all of -z's neighbourhood is the circle of radius pi):
#: on the crease and bumps maps turned away from +z, two channels beat three in local frames
#: at every rate up to 119 to 144 degrees, lose at low rates from 139 to 162 degrees, and lose
#: at every rate at 158 to 179 (BENCHMARKS, "Equidistant coordinates").
ONE_WAY = 0.75 * np.pi


#: :func:`octahedral`: most squared difference of the border pixels with their neighbours across
#: the fold, relative to the one with their neighbours inside, on every edge (at worst 0.93 and 1.01
#: on the normal maps of the fandisk and bunny meshes at 256 x 256; 3.0 on the shared acacia map,
#: 78 to 4,100 on the generated crease and bumps maps, 0 on the flat border of the bevel map); and
#: least squared difference of border pixels half an edge apart, relative to the one across the
#: fold, over the four edges (129 and 178 on fandisk and bunny; 0.89 to 1.04 on the maps that are
#: not glued, none on the bevel map's flat border). The second alone rejects every map that is not
#: glued, by a factor 15 or more; the first, edge by edge, keeps a map glued on some edges by chance
#: out (alone it would let the bevel map's flat border through).
FOLD_RATIO, FOLD_EVIDENCE = 2.0, 16.0


def faces_one_way(vectors: np.ndarray) -> bool:
    """Whether every unit vector of ``vectors`` (..., 3) lies within :data:`ONE_WAY` of +z."""
    return bool(np.all(vectors[..., 2] >= np.cos(ONE_WAY)))


def equidistant(vectors: np.ndarray) -> np.ndarray:
    """Azimuthal equidistant coordinates of unit normals: ``angle * (x, y) / |(x, y)|``, with
    ``angle`` the angle to +z (``bandelets.metrics.unit_normals`` inverts them).

    Parameters
    ----------
    vectors : ndarray, shape (H, W, 3)
        Unit vectors.

    Returns
    -------
    ndarray of float64, shape (H, W, 2), of length at most pi.

    Examples
    --------
    >>> tilted = np.array([[[np.sin(0.3), 0.0, np.cos(0.3)]]])
    >>> equidistant(tilted).round(12).tolist()
    [[[0.3, 0.0]]]
    """
    xy = np.asarray(vectors[..., :2], np.float64)
    across = np.sqrt(np.sum(xy * xy, axis=-1, keepdims=True))
    angle = np.arctan2(across, vectors[..., 2:3])
    # angle / sin(angle), 1 at the pole (where xy / across is undefined).
    return xy * np.divide(angle, across, out=np.ones_like(across), where=across > 0)


def octahedral(vectors: np.ndarray) -> bool:
    """Whether a normal map is an octahedral geometry image: glued across each edge to itself
    reversed about the edge's midpoint (see the module's docstring).

    On every edge, each border pixel must differ from its neighbour across the fold (the
    mirrored pixel of the same edge) no more than from its neighbour one pixel inside
    (:data:`FOLD_RATIO`, summed over the edge), and the border must turn: over the four edges,
    border pixels half an edge apart differ :data:`FOLD_EVIDENCE` times more than pixels across
    the fold. An ordinary map has no reason to be continuous with its border reversed: its fold
    pairs, far apart along the edge, differ as much as any pair half an edge apart. A map whose
    border is flat, or glued so by chance, has no evidence either way and is not taken for one.

    Parameters
    ----------
    vectors : ndarray, shape (H, W, 3)
        Unit vectors.

    Returns
    -------
    bool

    Examples
    --------
    >>> flat = np.zeros((16, 16, 3))
    >>> flat[..., 2] = 1.0
    >>> octahedral(flat)
    False
    """
    height, width = vectors.shape[:2]
    if height != width or height < 4:
        return False
    across = turn = 0.0
    for border, inside in (
        (vectors[0], vectors[1]),
        (vectors[-1], vectors[-2]),
        (vectors[:, 0], vectors[:, 1]),
        (vectors[:, -1], vectors[:, -2]),
    ):
        fold = float(np.sum((border - border[::-1]) ** 2))
        if fold > FOLD_RATIO * float(np.sum((border - inside) ** 2)):
            return False
        across += fold
        turn += float(np.sum((border - np.roll(border, height // 2, axis=0)) ** 2))
    return turn > FOLD_EVIDENCE * across
