"""What a normal map's array means before it is coded: its sample type and its layout.

* Unsigned integer samples (``uint8``, ``uint16``: an image's pixels, as a PNG or TIFF reader
  gives them) are mapped to ``[-1, 1]`` as :func:`bandelets.io.files.from_samples` maps PNG
  samples, and their depth is recorded, so that the decoder writes them back alike. Other
  integer types have no agreed meaning for a normal map and are refused.
* Two channels are ``x, y`` (BC5-style): ``z`` is rebuilt (:func:`bandelets.metrics.with_z`).
  With ``xy``, three channels are ``x, y`` and a blue that is not a normal component (often
  ambient occlusion): it is left out. The layout (:data:`bandelets.format.header.LAYOUTS`) is
  recorded; the decoder returns the same one. The encoder codes ``x, y`` as given, not
  renormalised: near the rim of the unit disc ``z`` changes fast with ``x, y``, and a vector
  beyond the rim (``z`` rebuilt as 0) pulled onto it decodes just inside, tilted. On the shared
  acacia map (2 % of its vectors beyond the rim) coding them as given lowers the 99th percentile
  angular error at 4 bpp without restoration from 12.8 to 9.3 degrees.

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

from ..io.files import integer_samples
from ..metrics import with_z

__all__ = ["ONE_WAY", "FOLD_RATIO", "FOLD_EVIDENCE", "prepare", "faces_one_way", "equidistant", "octahedral"]

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


def prepare(array, depth: int, xy: bool) -> tuple[np.ndarray | object, int, str]:
    """The normal map ``array`` as vectors of three components, its sample depth and its layout.

    Parameters
    ----------
    array : array_like, shape (H, W, 2) or (H, W, 3)
        Floats in ``[-1, 1]``, or ``uint8`` / ``uint16`` samples (``0`` is -1, the largest is 1).
    depth : {0, 8, 16}
        The caller's depth of the samples; must agree with an integer type.
    xy : bool
        Three channels hold ``x, y`` and an unused blue.

    Returns
    -------
    vectors : ndarray, float64, (H, W, 3) (or ``array`` itself when its shape is not one of the
        above: the encoder's checks then name what is wrong)
    depth : int
    layout : {"xyz", "xy", "rg"}
    """
    values, depth = integer_samples(np.asarray(array), "normal-map", depth)
    channels = values.shape[2] if values.ndim == 3 else 0
    if xy and channels != 3:
        raise ValueError(f"xy takes a normal map of 3 channels (x, y, unused blue), got shape {values.shape}")
    if channels == 2 or xy:
        return with_z(np.asarray(values[..., :2], np.float64)), depth, "xy" if channels == 2 else "rg"
    return values, depth, "xyz"


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
