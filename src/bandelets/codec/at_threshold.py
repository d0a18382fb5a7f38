"""One file at one threshold: the basis search, rate-distortion optimised quantization and the
entropy coding of coefficients already transformed (steps 8 to 11 of the paper).

Rate control calls :func:`encode_at_threshold` once per threshold it tries, with the same
coefficients: the wavelet transform and the lifting are done once.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..coding.image import code_image, new_coders
from ..coding.order import approximation_plan
from ..format.header import Header, pack
from ..format.quantizer import dequantize, quantize
from ..metrics import AngularError
from ..runtime.threads import each
from ..search.basis import best_trees
from ..search.lagrangian import LAMBDA
from ..search.quantization import optimise_bins
from ..transform import frames
from ..transform.bandeletize import bandeletize, debandeletize
from ..transform.bandelets import apply_trees
from ..transform.wavelets import subband_slices
from .pipeline import code_in_step, in_step

__all__ = ["RDOQ_LAMBDA", "Encoded", "encode_at_threshold"]


#: Lagrange multiplier of the choice between 0 and +-1 (:func:`bandelets.format.quantizer.optimise_bins`),
#: below the basis search's: its prices come from a first pass, and a coefficient dropped to 0
#: also makes its neighbours' contexts cheaper, which they do not count. 0.7 LAMBDA gained +0.04
#: to +0.05 dB BD-PSNR on the crease and bevel maps (-0.05 on the bumps, 0.00 to -0.01 on the
#: acacia door), 0.5 LAMBDA less: BENCHMARKS, "A step per wavelet level".
RDOQ_LAMBDA = 0.7 * LAMBDA


@dataclass(frozen=True)
class Encoded:
    """A .bdl file and what the encoder knows about it."""

    data: bytes
    threshold: float
    # Squared quantization error summed over all (padded) coefficients, before any restoration.
    coefficient_sse: float
    # PSNR of the decoded file at the source's depth, when the encoder has already measured it
    # (the restoration does), and what decode returns for the file.
    psnr: float | None = None
    decoded: np.ndarray | None = field(default=None, repr=False, compare=False)
    # What the file holds, as the decoder will find it: the quadtrees and the bins of every
    # channel, shape (H', W') (for the choice of the restoration, without decoding the file).
    header: Header | None = field(default=None, repr=False, compare=False)
    trees: list | None = field(default=None, repr=False, compare=False)
    bins: list | None = field(default=None, repr=False, compare=False)
    lifting: list | None = field(default=None, repr=False, compare=False)
    # A tiled file's angular error (:mod:`bandelets.codec.tile_encoder`), measured tile by tile: its decoded
    # image is not kept.
    angles: AngularError | None = field(default=None, repr=False, compare=False)


def encode_at_threshold(
    coefficients: list[np.ndarray], header: Header, lifting: list | None = None, search=best_trees
) -> Encoded:
    """Encode the channels, given their (padded) wavelet coefficients, at ``header.threshold``.

    Rate control calls this repeatedly with the same coefficients: the wavelet transform is
    done once, the basis search and the coding once per threshold. ``lifting``: the directions
    of the levels lifted along directions (:func:`bandelets.transform.directional.analysis`) when
    ``header.lifting``. ``search``: :func:`bandelets.search.basis.best_trees`, or a rate-control
    loop's :meth:`bandelets.search.treememo.TreeMemo.search` (its later encodes reuse the geometry).
    """
    threshold = header.threshold
    before, source = None, coefficients
    if header.frames:
        coefficients, before = _local_frames(source, header)
    trees = search(coefficients, header.levels, threshold, header.transform, header.transform_1d, before)
    # The channels in threads where the coding passes run in step (bandelets.codec.pipeline).
    bandelets = each(
        lambda c: apply_trees(c, header.levels, trees, bandeletize, header.transform_1d),
        coefficients,
        in_step(header),
    )
    quantized = [quantize(b, threshold) for b in bandelets]
    # Rate-distortion optimised quantization: a first coding pass prices every coefficient in
    # its context, then the bins between 0 and +-1 are chosen again and the image coded again
    # (on two cores, the two passes in step: bandelets.codec.pipeline).
    if in_step(header):
        coders, trees = code_in_step(bandelets, quantized, header, trees, lifting, RDOQ_LAMBDA)
        return _encoded(
            coders, header, threshold, _sse(bandelets, quantized, header), trees, quantized, lifting
        )
    prices = _prices(quantized, header, trees)
    if header.frames:
        # The frames of a level are made from the coarser levels as the decoder decodes them, so
        # from the bins chosen again: the levels are turned again, coarse to fine, each one's
        # bins chosen again (same trees, the first pass's prices) before the next one's frames
        # are made (+0.2 to +0.3 dB BD-PSNR on the normal maps of the fandisk and bunny meshes).
        del bandelets, quantized
        coefficients, before = _local_frames(source, header, prices)
        for index in range(len(trees)):
            before(index, trees)
        bandelets = [
            apply_trees(c, header.levels, trees, bandeletize, header.transform_1d) for c in coefficients
        ]
        quantized = [quantize(b, threshold) for b in bandelets]
    del coefficients, source
    for b, q, bits in zip(bandelets, quantized, prices, strict=True):
        optimise_bins(b, q, bits, threshold, RDOQ_LAMBDA)
    del prices
    sse = _sse(bandelets, quantized, header)
    del bandelets  # not held while coding: the peak of a large image's encoding
    coders = new_coders()
    trees, _, _ = code_image(coders, header, trees, [q.ravel() for q in quantized], lifting=lifting)
    return _encoded(coders, header, threshold, sse, trees, quantized, lifting)


def _sse(bandelets: list[np.ndarray], quantized: list[np.ndarray], header: Header) -> float:
    """The squared quantization error of the bins ``quantized`` of ``bandelets``, summed."""
    # The weighted normal component's error is the weight times the error it makes.
    scales = (header.normal_weight, 1.0, 1.0) if header.frames else (1.0,) * len(bandelets)
    return sum(
        float(np.sum((b - dequantize(q, header.threshold)) ** 2)) / scale**2
        for b, q, scale in zip(bandelets, quantized, scales, strict=True)
    )


def _encoded(
    coders: tuple, header: Header, threshold: float, sse: float, trees, quantized, lifting
) -> Encoded:
    """The file of the streams ``coders`` have coded, and what the encoder knows of it."""
    # Format version 19: the streams stored level by level (bandelets.format.levels).
    segments = tuple(zip(*([len(p) for p in c.segments] for c in coders), strict=True))
    header = replace(header, segments=segments)
    data = pack(header, tuple(b"".join(c.segments) for c in coders))
    return Encoded(data, threshold, sse, header=header, trees=trees, bins=quantized, lifting=lifting)


def _prices(quantized: list, header: Header, trees: list) -> list[np.ndarray]:
    """The bits a first coding pass spends on every coefficient of ``quantized``, shape (H', W')
    per channel, 0 on the approximation (coded as a prediction residual: left alone), as
    :func:`bandelets.format.quantizer.optimise_bins` takes them."""
    _, _, spent = code_image(new_coders(), header, trees, [q.ravel() for q in quantized])
    approximation = approximation_plan(quantized[0].shape, header.levels).order
    for bits in spent:
        bits[approximation] = 0.0
    return [bits.reshape(quantized[0].shape) for bits in spent]


def _local_frames(coefficients: list[np.ndarray], header: Header, prices: list | None = None):
    """The coefficients to turn into local frames, and the ``before`` hook of :func:`best_trees`
    that turns each level just before the basis search reaches it.

    The frames of a level come from the approximation and the coarser levels exactly as the
    decoder will decode them (:func:`bandelets.transform.frames.to_global`): quantized with the trees
    already chosen, their bins chosen again with ``prices`` when given
    (:func:`bandelets.format.quantizer.optimise_bins`, as the encoder then codes them), dequantized and
    turned back.
    """
    t, levels, t1d = header.threshold, header.levels, header.transform_1d
    args = (header.wavelet, levels, header.extension)
    shape = coefficients[0].shape
    h, w = shape[0] >> levels, shape[1] >> levels
    local = [c.copy() for c in coefficients]
    decoded = [np.zeros(shape) for _ in coefficients]  # what the decoder has so far, global frame
    for c, d in zip(coefficients, decoded, strict=True):
        d[:h, :w] = dequantize(quantize(c[:h, :w], t), t)
    slices = subband_slices(shape, levels)
    turned = []  # the frames of the level turned last

    def before(index: int, trees: list) -> None:
        if index % 3:
            return
        if turned:  # decode the level just searched, as the decoder will
            for i in range(index - 3, index):
                where = slices[i][2]
                for k, (c, d) in enumerate(zip(local, decoded, strict=True)):
                    b = bandeletize(c[where], trees[i], t1d)
                    q = quantize(b, t)
                    if prices is not None:
                        optimise_bins(b, q, prices[k][where], t, RDOQ_LAMBDA)
                    d[where] = debandeletize(dequantize(q, t), trees[i], t1d)
            frames.rotate(
                decoded, turned[-1], slices[index - 1][0], levels, header.normal_weight, local=False
            )
        level = slices[index][0]
        turned[:] = [frames.level_frames(decoded, level, *args, header.kind)]
        frames.rotate(local, turned[-1], level, levels, header.normal_weight, local=True)

    return local, before
