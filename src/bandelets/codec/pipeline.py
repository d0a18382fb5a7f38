"""An encoder's two coding passes at one threshold, in step on two cores.

:func:`bandelets.codec.at_threshold.encode_at_threshold` codes the image twice: a first pass prices
every coefficient in its context, then the bins between 0 and +-1 are chosen again
(:func:`bandelets.search.quantization.optimise_bins`) and the file is coded. The choice of a bin needs
only its own price, and a pass reads the bins of the subband it codes and nothing finer, so the
second pass may code a subband as soon as the first has priced it: here the first pass runs in a
worker thread (the coder's kernels let go of the GIL) and the second follows it subband by subband
in the calling thread. The files are the same bytes as the passes one after the other.
"""

from __future__ import annotations

import threading

import numpy as np

from ..coding.image import code_image, new_coders
from ..format.fields import padded_shape
from ..format.header import Header
from ..runtime.threads import spare_core, workers
from ..search.quantization import optimise_bins
from ..transform.wavelets import subband_slices

__all__ = ["IN_STEP_FROM", "code_in_step", "in_step"]

#: Pixels from which the two passes run in step: at 512 x 512 (vent decal and crease maps, 1 bpp) the
#: overlap took 3 to 5 % off the encode's wall time but added 2 to 3 % of CPU time (the hand-over of
#: every subband); at 2048 x 2048, 14 to 16 % off the wall time for the same CPU time.
IN_STEP_FROM = 1024 * 1024


def in_step(header: Header) -> bool:
    """Whether :func:`code_in_step` codes a file of ``header``: a second core, an image of
    :data:`IN_STEP_FROM` pixels, no local frames (whose levels are turned with the first pass's
    prices, :mod:`bandelets.codec.at_threshold`), and a calling thread that does not already share
    the cores with the library's others (a tile of a tiled encode, :func:`thread_map`'s items)."""
    large = header.height * header.width >= IN_STEP_FROM
    return large and not header.frames and spare_core()


def code_in_step(
    bandelets: list[np.ndarray],
    quantized: list[np.ndarray],
    header: Header,
    trees: list,
    lifting: list | None,
    lagrangian: float,
) -> tuple[tuple, list]:
    """The coders of the file and the trees coded (:func:`bandelets.coding.image.code_image`) of
    ``quantized`` (the bins of ``bandelets``, shape (H', W') per channel), whose bins between 0 and
    +-1 are chosen again on the way (in place, with ``lagrangian``) from the prices of a first pass
    run in a worker thread, a subband ahead."""
    shape = padded_shape((header.height, header.width), header.levels)
    slices = subband_slices(shape, header.levels)
    flat = [q.ravel() for q in quantized]
    prices = [np.zeros(shape[0] * shape[1]) for _ in quantized]
    plans: dict = {}
    state = threading.Condition()
    priced = [0, False]  # subbands the first pass has coded; whether it has stopped

    def reached(index: int) -> None:
        with state:
            priced[0] = index
            state.notify_all()

    def first_pass() -> None:
        try:
            code_image(new_coders(), header, trees, flat, reached=reached, plans=plans, spent=prices)
        finally:
            with state:
                priced[1] = True
                state.notify_all()

    future = workers().submit(first_pass)

    def chosen(index: int) -> None:
        """The bins of subband ``index`` chosen again, once the first pass has priced it."""
        if index == len(slices):
            return
        with state:
            state.wait_for(lambda: priced[0] > index or priced[1])
        if priced[0] <= index:
            future.result()  # the first pass's error
        where = slices[index][2]
        for b, q, bits in zip(bandelets, quantized, prices, strict=True):
            optimise_bins(b[where], q[where], bits.reshape(shape)[where], header.threshold, lagrangian)

    coders = new_coders()
    try:
        # The second pass writes its code lengths, which nothing reads, over the prices of the subbands
        # it has chosen the bins of (the first pass is past them) and of the approximation (whose bins
        # are not chosen again): no image of them more in memory.
        trees, _, _ = code_image(
            coders, header, trees, flat, lifting=lifting, reached=chosen, plans=plans, spent=prices
        )
    finally:
        future.result()
    return coders, trees
