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

Those whose normals face one way are coded as two channels of equidistant coordinates, and
the normals of an octahedral geometry image are glued across the border: both found by
:mod:`bandelets.transform.normals`.
"""

from __future__ import annotations

import numpy as np

from ..format.fields import Kind, Layout
from ..format.samples import integer_samples
from ..transform.normals import with_z

__all__ = ["prepare"]


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
    values, depth = integer_samples(np.asarray(array), Kind.NORMAL_MAP, depth)
    channels = values.shape[2] if values.ndim == 3 else 0
    if xy and channels != 3:
        raise ValueError(f"xy takes a normal map of 3 channels (x, y, unused blue), got shape {values.shape}")
    if channels == 2 or xy:
        layout = Layout.XY if channels == 2 else Layout.RG
        return with_z(np.asarray(values[..., :2], np.float64)), depth, layout
    return values, depth, Layout.XYZ
