"""Rate-distortion optimised quantization: the encoder's second look at the bins between 0 and +-1.

The quantizer :func:`bandelets.format.quantizer.quantize` decides on magnitude alone; the decoder
needs nothing more than the bins. The encoder, once a first coding pass has priced every
coefficient in its context, moves a few of them across the dead zone's edge where that lowers
``error + lambda T**2 bits`` (:func:`optimise_bins`).
"""

from __future__ import annotations

import numpy as np

from ..format.quantizer import PROMOTE_ABOVE, RECONSTRUCTION

__all__ = ["optimise_bins"]


#: Bits a significant coefficient spends besides its significance (sign, first magnitude flag).
_SIGN_AND_MAGNITUDE_BITS = 1.5


def optimise_bins(
    values: np.ndarray, q: np.ndarray, bits: np.ndarray, threshold: float, lagrangian: float
) -> None:
    """Rate-distortion optimised quantization between 0 and +-1, in place.

    ``Q_T`` decides on magnitude alone; here a coefficient of bin 1 becomes 0, or a value of
    the dead zone above ``PROMOTE_ABOVE T`` becomes +-1, when that lowers
    ``error + lagrangian T**2 bits``. The bits come from a first coding pass: a coefficient's
    ideal code length prices its own choice, and the probability of significance its context
    had (``2**-bits`` for a zero, about ``2**(1.5 - bits)`` for a +-1) prices the other one.

    Parameters
    ----------
    values : ndarray of float, shape (H, W)
        The coefficients quantized.
    q : ndarray of int32, shape (H, W)
        Their bin indices; modified.
    bits : ndarray of float, shape (H, W)
        Ideal code length of each coefficient in the first pass; 0 where not to be touched.
    threshold : float
    lagrangian : float
        Lagrange multiplier, in ``T**2`` per bit (the encoder passes the basis search's,
        :data:`bandelets.search.lagrangian.LAMBDA`).
    """
    price = lagrangian * threshold * threshold
    a = np.abs(values)
    # Error removed by coding +-1 instead of 0.
    gain = a * a - (a - (1.0 + RECONSTRUCTION) * threshold) ** 2
    ones = (np.abs(q) == 1) & (bits > 0)
    significant = np.clip(2.0 ** (_SIGN_AND_MAGNITUDE_BITS - bits[ones]), 0.0, 0.5)
    saved = bits[ones] + np.log2(1.0 - significant)
    drop = np.zeros(q.shape, bool)
    drop[ones] = gain[ones] < price * saved
    zeros = (q == 0) & (bits > 0) & (a > PROMOTE_ABOVE * threshold)
    significant = np.clip(1.0 - 2.0 ** -bits[zeros], 1e-6, 1.0)
    extra = _SIGN_AND_MAGNITUDE_BITS - np.log2(significant) - bits[zeros]
    promote = np.zeros(q.shape, bool)
    promote[zeros] = gain[zeros] > price * extra
    q[drop] = 0
    q[promote] = np.sign(values[promote]).astype(q.dtype)
