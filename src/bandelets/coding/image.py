"""Coding of a whole image's quadtrees and bins into the three streams of a .bdl file, and back.

One function, :func:`code_image`, walks the image in the order of the file for both the
encoder and the decoder, so the two cannot disagree on it.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np

from ..format.fields import padded_shape
from ..format.header import Header
from ..runtime.threads import spare_core, workers
from ..transform.bandeletize import debandeletize_bins
from ..transform.quadtree import flat_quadtree, root_width
from ..transform.wavelets import subband_slices
from . import approximation, coefficients, directions, rangecoder
from .order import approximation_plan, subband_plan
from .squarecontexts import square_hints
from .trees import N_DIRECTION_CONTEXTS, N_SPLIT_CONTEXTS, code_tree, reference_of

__all__ = ["AHEAD_FROM", "code_image", "code_lifting", "new_coders"]

#: Padded pixels from which a decoder decodes a subband's quadtree ahead, in a worker thread.
AHEAD_FROM = 256 * 256


def _activity(known: list[np.ndarray], shape: tuple[int, int], levels: int, index: int):
    """Activity of the coarser subband under squares of detail subband ``index``.

    Returns ``(rows, cols, widths) -> bucket``: 0 if every already coded coefficient (all
    channels) of the parent region is 0, 1 if their magnitudes sum to at most 2, 2 above;
    3 for the coarsest detail level, whose parent is the approximation.
    """
    if index < 3:
        return lambda rows, cols, widths: np.full(np.broadcast(rows, cols, widths).shape, 3)
    where = subband_slices(shape, levels)[index - 3][2]
    magnitude = sum(np.abs(k.reshape(shape)[where]) for k in known)
    table = np.zeros((magnitude.shape[0] + 1, magnitude.shape[1] + 1), np.int64)
    table[1:, 1:] = magnitude.cumsum(0).cumsum(1)

    def bucket(rows, cols, widths):
        rows, cols, widths = np.broadcast_arrays(rows, cols, widths)
        r0, c0 = rows // 2, cols // 2
        r1 = np.minimum((rows + widths) // 2, magnitude.shape[0])
        c1 = np.minimum((cols + widths) // 2, magnitude.shape[1])
        total = table[r1, c1] - table[r0, c1] - table[r1, c0] + table[r0, c0]
        return np.where(total == 0, 0, np.where(total <= 2, 1, 2))

    return bucket


def code_image(
    coders: tuple,
    header: Header,
    trees: list | None = None,
    quantized: list[np.ndarray] | None = None,
    estimate: bool = False,
    *,
    lifting: list | None = None,
    upto: int = 0,
    reached: Callable[[int], None] | None = None,
    plans: dict | None = None,
    spent: list[np.ndarray] | None = None,
) -> tuple[list, list, list]:
    """Code (``trees`` and ``quantized`` given) or decode everything the streams hold.

    Order: the approximation of every channel, then subband by subband (coarse to fine,
    H, V, D): its quadtree and directions (:mod:`bandelets.coding.trees`), then for each
    channel its bandelet squares and the rest of its coefficients (:mod:`bandelets.coding.order`).
    The guide of a channel (a context, see :func:`bandelets.coding.coefficients.code_coefficients`) is
    what the previous channel coded, bandelet coefficients included. After a channel's
    bandelet squares, the contexts are given the wavelet coefficients those
    squares decode to.

    Format version 19: the streams are cut (:meth:`bandelets.coding.rangecoder.Coder.cut`) after
    the approximation and after each level's three subbands, so that the file stores them level by
    level (:mod:`bandelets.format.levels`); the directions of the levels lifted along directions
    (:func:`code_lifting`, into ``lifting``: the fields to code, or a list the decoded ones are
    appended to) end the directions of the coarsest lifted level. ``upto``: decode the levels
    coarser than ``upto`` only (1 = finest; 0: all), the bins of the others left at zero; the
    trees returned are then those of the levels decoded.

    ``reached``: called with ``index`` before detail subband ``index`` is coded, and with the count
    of subbands after the last (an encoder's two passes in step, :mod:`bandelets.codec.pipeline`).
    ``plans``: the coding orders of the subbands by index (:func:`bandelets.coding.order.subband_plan`),
    taken out where present and added where not (of two passes over the same trees, the first adds
    them and the second takes them: each plan is made once and held no longer than the second needs).
    ``spent``: where the code lengths are written (zeros, shape (H * W,) per channel; made if None).

    ``estimate``: the approximation is coded with version 17's model
    (:func:`bandelets.coding.coefficients.code_coefficients`), not the file's
    (:mod:`bandelets.coding.approximation`),
    for the level choice's prices (:mod:`bandelets.search.levelchoice`): no file is made that way.

    Returns
    -------
    trees : list of Quadtree
    quantized : list of ndarray of int32, shape (H * W,), per channel
    spent : list of ndarray of float64, shape (H * W,): ideal code length of every coefficient
    """
    splits, dirs, coeffs = coders
    shape = padded_shape((header.height, header.width), header.levels)
    size = shape[0] * shape[1]
    decoding = quantized is None
    if decoding:
        quantized = [np.zeros(size, np.int32) for _ in range(header.channels)]
    known = [np.zeros(size, np.int64) for _ in quantized]
    spent = [np.zeros(size) for _ in quantized] if spent is None else spent
    coarse = approximation_plan(shape, header.levels)
    guides = [np.zeros(0, np.int32)] + quantized[:-1]
    for c, q in enumerate(quantized):
        code = coefficients.code_coefficients if estimate else approximation.code_approximation
        code(coeffs, q, coarse, known[c], guides[c], spent[c])
    segments = [[] for _ in coders]
    _cut(coders, segments)
    out = []
    slices = subband_slices(shape, header.levels)
    geometry = partial(
        _geometry, coders, segments, header, None if decoding else trees, out, known, lifting, plans, decoding
    )
    # A decoder decodes the next subband's quadtree in a worker thread while it decodes the bins of
    # this one (the streams are apart; the quadtree's contexts read the subbands decoded before).
    ahead = decoding and size >= AHEAD_FROM and spare_core()
    pending = None
    for index, (_, _, where) in enumerate(slices):
        if header.levels - index // 3 <= upto:
            break
        if reached is not None:
            reached(index)
        tree, (squares, rest) = geometry(index) if pending is None else pending.result()
        out.append(tree)
        pending = None
        if ahead and index + 1 < len(slices) and header.levels - (index + 1) // 3 > upto:
            pending = workers().submit(geometry, index + 1)
        for c, q in enumerate(quantized):
            if squares.order.size:
                hints = square_hints(known[c], shape, header.levels, index, tree, header.transform_1d)
                coefficients.code_coefficients(coeffs, q, squares, known[c], guides[c], spent[c], hints)
                view = known[c].reshape(shape)[where]
                debandeletize_bins(view, tree, header.threshold, header.transform_1d)
            coefficients.code_coefficients(coeffs, q, rest, known[c], guides[c], spent[c])
        if index % 3 == 2:  # the coefficients' stream cut after each level (the trees': _geometry)
            _cut(coders[2:], segments[2:])
    if reached is not None:
        reached(len(slices))
    if not decoding:
        for coder, parts in zip(coders, segments, strict=True):
            coder.segments = parts
    return out, quantized, spent


def _geometry(
    coders: tuple,
    segments: list,
    header: Header,
    trees: list | None,
    out: list,
    known: list[np.ndarray],
    lifting: list | None,
    plans: dict | None,
    decoding: bool,
    index: int,
):
    """The quadtree of detail subband ``index`` (``trees[index]`` coded, or decoded; ``out``: those of
    the subbands before it) and its coding order (:func:`bandelets.coding.order.subband_plan`, taken
    out of ``plans`` where there, else added to it); after the last subband of a level, the lifting's
    directions (:func:`code_lifting`) and the cut of the trees' two streams. Reads ``known`` on the
    subband of the level above only (:func:`_activity`): a decoder runs it while it decodes the bins of
    ``index - 1``."""
    splits, dirs, _ = coders
    shape = padded_shape((header.height, header.width), header.levels)
    _, orientation, where = subband_slices(shape, header.levels)[index]
    band = (where[0].stop - where[0].start, where[1].stop - where[1].start)
    if header.transform == "bandelet":
        tree = code_tree(
            splits,
            dirs,
            None if decoding else trees[index],
            band,
            reference_of(out, index, orientation),
            _activity(known, shape, header.levels, index),
        )
    else:
        tree = flat_quadtree(band, root_width(band))
    plan = None if plans is None else plans.pop(index, None)
    if plan is None:
        plan = subband_plan(shape, header.levels, index, tree, header.transform_1d)
        if plans is not None:
            plans[index] = plan
    if index % 3 == 2:
        level = header.levels - index // 3
        if level == header.lifting and (decoding or lifting is not None):  # else: a price only
            fields = code_lifting(dirs, header, None if decoding else lifting)
            if decoding and lifting is not None:
                lifting.extend(fields)
        _cut(coders[:2], segments[:2])
    return tree, plan


def _cut(coders: tuple, segments: list[list[bytes]]) -> None:
    """End the segment of every stream (:meth:`bandelets.coding.rangecoder.Coder.cut`)."""
    for coder, parts in zip(coders, segments, strict=True):
        following = None
        if coder.decoding:
            following = coder.pending.pop(0) if coder.pending else b""
        parts.append(coder.cut(following))


def code_lifting(coder: rangecoder.Coder, header: Header, lifting: list | None = None) -> list | None:
    """Code (``lifting`` given) or decode the directions of the levels lifted along directions
    (:func:`bandelets.transform.directional.code_fields`), which end the directions of the coarsest
    lifted level (:func:`code_image` calls it); None for a file without them."""
    if not header.lifting:
        return None
    shape = padded_shape((header.height, header.width), header.levels)
    return directions.code_fields(coder, lifting, shape, header.lifting, N_DIRECTION_CONTEXTS)


def new_coders(data: tuple | None = None) -> tuple[rangecoder.Coder, ...]:
    """Coders of the three streams (splits, directions, coefficients): encoders, or decoders of ``data``,
    each stream its bytes or the list of its segments, level by level
    (:func:`bandelets.format.levels.parts`).

    An encoder's segments are its ``segments`` after :func:`code_image`."""
    sizes = (N_SPLIT_CONTEXTS, N_DIRECTION_CONTEXTS + directions.N_CONTEXTS, approximation.N_CONTEXTS)
    coders = []
    for i, n in enumerate(sizes):
        parts = None if data is None else data[i]
        parts = [parts] if isinstance(parts, (bytes, bytearray)) else parts
        coder = rangecoder.Coder(n, None if parts is None else parts[0])
        coder.pending = [] if parts is None else list(parts[1:])
        coder.segments = []
        coders.append(coder)
    return tuple(coders)
