"""Entropy coding of the direction fields of the lifting (:mod:`bandelets.transform.directional`),
in the directions stream.
"""

from __future__ import annotations

import numpy as np

from ..format.fields import MAX_LIFTING, FormatError
from ..transform.directional import OFFSETS, field_shapes
from . import rangecoder

__all__ = ["N_CONTEXTS", "code_fields"]


_N_STATE = 3


#: The "moved" flag of a block counts its left and upper neighbours moved too (0 to 2).
_N_NEAR = 3


#: Contexts of the direction coder: "moved" flags by pass, level and neighbours, then the symbols'
#: one model.
N_CONTEXTS = 2 * MAX_LIFTING * _N_STATE * _N_NEAR + 16


def code_fields(coder: rangecoder.Coder, fields: list[np.ndarray] | None, shape, lifting: int, base: int):
    """Code (``fields`` given) or decode the direction codes of every pass.

    Coarse level first, rows pass then columns pass. Each block's "moved" flag (a direction other
    than the plain one) has the context of its pass, of the block coded before at its place: in
    the rows pass of the same level for a columns pass, in the rows pass of the next coarser level
    for a rows pass (none for the coarsest), and of how many of its left and upper neighbours
    moved (since format version 11: a crease moves a line of blocks; 10 to 16 % fewer bits for the
    directions of the 256 x 256 crease and fandisk normal maps at 0.5 and 1 bpp). The other codes
    are symbols of one adaptive model for every pass (format version 17: the passes choose alike,
    and a model per pass spent 6 to 8 % more on the symbols of the fandisk rendered from the top
    at 256, learning its 14 codes six times over a few dozen blocks each). Contexts from
    ``base`` on (:data:`N_CONTEXTS` of them).
    """
    shapes = field_shapes(shape, lifting)
    out: list = [None] * len(shapes)
    for level in range(lifting - 1, -1, -1):
        for p in (0, 1):
            i = 2 * level + p
            size = shapes[i]
            if p == 1:
                state = (out[i - 1] == 0).T.astype(np.int64)
            elif level + 1 < lifting:
                coarse = out[i + 2] == 0
                r = np.minimum(np.arange(size[0]) // 2, coarse.shape[0] - 1)
                c = np.minimum(np.arange(size[1]) // 2, coarse.shape[1] - 1)
                state = coarse[r[:, None], c[None, :]].astype(np.int64)
            else:
                state = np.full(size, 2, np.int64)
            codes = np.zeros(size, np.int64) if fields is None else np.asarray(fields[i], np.int64)
            contexts = base + (i * _N_STATE + state) * _N_NEAR
            moved = np.nonzero(rangecoder.code_flag_map(coder, codes != 0, contexts, 1).ravel())[0]
            symbols = rangecoder.code_symbols(
                coder,
                codes.ravel()[moved] - 1,
                np.full(moved.shape, base + 2 * MAX_LIFTING * _N_STATE * _N_NEAR),
                np.full(moved.shape, 4),
            )
            if np.any(symbols >= len(OFFSETS) - 1):
                raise FormatError("corrupt .bdl file: lifting direction out of range")
            decoded = np.zeros(size[0] * size[1], np.int64)
            decoded[moved] = symbols + 1
            out[i] = decoded.reshape(size)
    return out
