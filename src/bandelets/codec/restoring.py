"""The encoder's choice of what the decoder does after dequantizing: the count of restoration
iterations (:mod:`bandelets.restore.restoration`) and the loop filter
(:mod:`bandelets.restore.loopfilter`, fitted by :mod:`bandelets.search.filterfit`) written into a file.
"""

from __future__ import annotations

from dataclasses import replace
from itertools import islice

import numpy as np

from ..format.fields import MAX_RESTORATION, FormatError
from ..format.header import pack, unpack
from ..format.limits import OWN_FILE, check_memory, restoration_work
from ..restore import loopfilter
from ..runtime.progress import Progress
from ..search.lagrangian import LAMBDA
from .at_threshold import Encoded
from .decoder import decoded_image, restorations
from .options import EncodeOptions

__all__ = ["RESTORATION_SHARE", "squared_error_of", "with_loop_filter", "with_restoration"]


#: The encoder stops trying more restoration iterations this many after the best so far.
_RESTORATION_PATIENCE = 10


#: Of the restoration's gain in PSNR over plain dequantization, the share the count written into
#: the file keeps: the fewest iterations that reach it, not the best (the PSNR flattens out near
#: the best: on the 512 x 512 crease map at 1 bpp 39 iterations instead of 45 keep 97 % of 5.9 dB,
#: and decode 13 % faster).
RESTORATION_SHARE = 0.97


def squared_error_of(psnr: float, peak: float, samples: int) -> float:
    """The summed squared error of ``samples`` values that a PSNR of ``psnr`` dB stands for."""
    return 0.0 if psnr == float("inf") else samples * peak**2 * 10.0 ** (-psnr / 10.0)


#: Copies of the restored channels the encoder keeps while it searches, so that the channels of
#: the count chosen need not be made again (for the loop filter): at most _KEPT, of at most
#: _KEPT_BYTES together (none of a 2048 x 2048 map: made again, the encoder's peak memory stays).
_KEPT, _KEPT_BYTES = 3, 16 * 2**20


def with_restoration(
    encoded: Encoded, measure, options: EncodeOptions, line: Progress, keep: bool
) -> tuple[Encoded, np.ndarray]:
    """``encoded`` with the fewest restoration iterations whose decoded channels keep
    :data:`RESTORATION_SHARE` of the best gain in score by ``measure``
    (:func:`bandelets.metrics.psnr_of_channels`) written into its header (at most as many as
    ``options.max_work`` allows a decoder; none without ``options.restore``), that score and
    (``keep``) that decoded image; and the decoded channels (C, H', W')."""
    header = encoded.header
    most = 0
    if options.restore:
        try:
            check_memory(replace(header, restoration=1), options.max_memory)
            most = min(MAX_RESTORATION, options.max_work // restoration_work(replace(header, restoration=1)))
        except FormatError:  # the decoder could not afford it either
            pass
    scores: list[float] = []
    # Copies of the channels of the iterations that may be chosen (at most _KEPT_BYTES): the one
    # chosen is then not made again.
    kept: dict[int, np.ndarray] = {}
    line.stage("restoration search", restart=True)
    for n, channels in enumerate(restorations(header, encoded.trees, encoded.bins, encoded.lifting)):
        scores.append(measure(channels))
        line.step(f"T={header.threshold:.3g}: {scores[-1]:.2f} dB")
        if n >= most or n - int(np.argmax(scores)) >= _RESTORATION_PATIENCE:
            break
        # Only the iterations that keep the share of the best gain so far can be the one chosen
        # (the share of the final best is larger): copies of those, the earliest first.
        share = scores[0] + RESTORATION_SHARE * (max(scores) - scores[0])
        kept = {k: c for k, c in kept.items() if scores[k] >= share}
        if scores[n] >= share and len(kept) < _KEPT and (len(kept) + 1) * channels.nbytes <= _KEPT_BYTES:
            kept[n] = channels.copy()
    line.stage("rate control")
    best = int(np.argmax(scores))
    if best > 0:  # the fewest iterations that keep the share (the plain decoding if no gain)
        best = next(
            n for n, s in enumerate(scores) if s - scores[0] >= RESTORATION_SHARE * (scores[best] - scores[0])
        )
    if best in kept:
        channels = kept[best]
    elif best != len(scores) - 1:  # the iterations work in place: made again up to the count chosen
        channels = next(
            islice(restorations(header, encoded.trees, encoded.bins, encoded.lifting), best, None)
        )
    output = decoded_image(channels, header) if keep else None
    if best == 0:
        return replace(encoded, psnr=scores[0], decoded=output), channels
    header, streams = unpack(encoded.data, **OWN_FILE)
    data = pack(replace(header, restoration=best), streams)
    return replace(encoded, data=data, psnr=scores[best], decoded=output), channels


def with_loop_filter(
    encoded: Encoded, channels: np.ndarray, targets: np.ndarray, measure, to_error, budget, keep: bool
) -> Encoded:
    """``encoded`` with the loop filter :func:`bandelets.restore.loopfilter.choose` finds for its decoded
    ``channels`` against ``targets`` (none if none pays; at most ``budget`` bytes), its score by
    ``measure`` and (``keep``) its decoded image; ``to_error``: a score to the squared error."""
    header = encoded.header
    found, filtered = loopfilter.choose(
        channels, targets, header.threshold, LAMBDA, lambda c: to_error(measure(c)), budget, header.folded
    )
    if found is None:
        return replace(encoded, decoded=decoded_image(channels, header) if keep else None)
    header, streams = unpack(encoded.data, **OWN_FILE)
    data = pack(replace(header, loop_filter=found), streams)
    output = decoded_image(filtered, header) if keep else None
    return replace(encoded, data=data, psnr=measure(filtered), decoded=output)
