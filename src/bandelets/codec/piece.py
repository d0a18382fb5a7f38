"""Encoding of one piece: an image coded as one .bdl file (a whole image, or one tile of a tiled one).

The steps, in order:

1. the plan (:func:`bandelets.codec.plan.plan_image`): channels, layout, levels;
2. the first :class:`~bandelets.codec.alternatives.Candidate`: the wavelet coefficients, with the
   count of levels chosen at the threshold expected (:mod:`bandelets.search.levelchoice`);
3. the choice among the alternatives at that threshold (:meth:`_PieceEncoder.choose`): directions,
   the Riesz pair, and those close enough to paying that a rate target tries them too;
4. the threshold: given, or searched by rate control for a size or a quality
   (:mod:`bandelets.search.ratecontrol`), each try a whole file at one threshold
   (:func:`bandelets.codec.at_threshold.encode_at_threshold`);
5. what the decoder is told to do after dequantizing (:mod:`bandelets.codec.restoring`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from .. import metrics
from ..format.fields import MAX_THRESHOLD, MIN_THRESHOLD, Kind, Layout
from ..format.header import HEADER_BYTES, Header, pack, unpack
from ..format.limits import OWN_FILE
from ..format.samples import as_read
from ..restore import loopfilter
from ..runtime.progress import Progress
from ..runtime.threads import CORES, thread_map
from ..search import ratecontrol
from ..search.basis import best_trees
from ..search.levelchoice import levels_to_try
from ..search.treememo import TreeMemo
from ..transform import normals
from ..transform.bandelets import wavelet_coefficients
from .alternatives import (
    RIESZ_PAYS_BELOW,
    RIESZ_TRIAL_BELOW,
    TRIAL_PIXELS,
    Candidate,
    lifted,
    lifting_levels_for,
    raised_t_max,
    riesz_pair,
    with_levels,
)
from .at_threshold import Encoded, encode_at_threshold
from .decoder import decode_parsed, decoded_bins, decoded_from_bins
from .options import FULL_TRIALS_FROM, TRIALS_FROM, EncodeOptions
from .piecememo import PieceMemo
from .plan import plan_image
from .restoring import squared_error_of, with_loop_filter, with_restoration

__all__ = ["PROBE_BIAS", "encode_piece"]

#: A rate target's first file is encoded where a wavelet file, priced as the bandelet file at
#: ``exp(PROBE_BIAS / bpp)`` times its size, meets the target (:func:`bandelets.search.ratecontrol.for_size`):
#: the median of that ratio over the maps of issue 15 at 0.25 to 2 bpp (1.005 to 1.036 at 1 bpp).
PROBE_BIAS = 0.016


def encode_piece(
    array,
    options: EncodeOptions,
    *,
    bpp: float | None = None,
    threshold: float | None = None,
    psnr: float | None = None,
    max_angle: float | None = None,
    measured: bool = False,
    unrestored: Encoded | None = None,
    memo: PieceMemo | None = None,
) -> Encoded:
    """Encode ``array`` in one piece for exactly one target (checked by the caller,
    :func:`bandelets.codec.encoder.encode_with_stats`, whose options and returns these are).

    ``unrestored``: what this function returned for the same array and options but no restoration,
    at ``threshold``: the file is then only restored and measured, not coded again (a tiled
    encode's last pass, :mod:`bandelets.codec.tile_encoder`). ``memo``: with ``threshold``, the
    directions and geometry of this piece's first encode at a nearby threshold, reused
    (:class:`bandelets.codec.piecememo.PieceMemo`; a tile across the passes of rate control).
    """
    with Progress(options.progress) as line:
        piece = _PieceEncoder(
            array, options, line, measured, bpp=bpp, threshold=threshold, psnr=psnr, max_angle=max_angle
        )
        if unrestored is not None:
            piece.choose(None)
            return piece.finish(_read_back(unrestored))
        if threshold is not None:
            piece.memo = memo
            candidate, _ = piece.choose(float(threshold))
            search = best_trees if memo is None else memo.trees.search
            return piece.finish(piece.encode_at(candidate, float(threshold), search=search))
        line.stage("rate control")
        if bpp is not None:
            return piece.for_size(bpp)
        return piece.for_quality(psnr=psnr, max_angle=max_angle)


@dataclass
class _Measures:
    """What the files a piece tries are measured against (made by :meth:`_PieceEncoder.choose`)."""

    #: Score of decoded channels (C, H', W') as written at the source's depth
    #: (:func:`bandelets.metrics.psnr_of_channels`), for the restoration and the loop filter.
    channels: object = None
    #: (C, H, W) float32: what the coded channels stand for, the loop filter's fit.
    planes: np.ndarray | None = None
    #: A score to the summed squared error it stands for.
    to_error: object = None


class _PieceEncoder:
    """The state of one piece's encoding: its plan and candidate, the source while it is measured."""

    def __init__(
        self,
        array,
        options: EncodeOptions,
        line: Progress,
        measured: bool,
        *,
        bpp,
        threshold,
        psnr,
        max_angle,
    ) -> None:
        self.options, self.line, self.measured = options, line, measured
        # The decoded image is kept for the caller (measured) or the angular target.
        self.keep = measured or max_angle is not None
        self.plan, x, self.coded = plan_image(array, options)
        del array
        plan = self.plan
        self._psnr = None  # the measure against the reference, made when first needed
        self.measures = _Measures()
        #: The threshold and wavelet file of the candidate :meth:`_cheapest` chose.
        self.probed: tuple[float, Encoded] | None = None
        #: The choices of an encode of the same piece at a nearby threshold (:func:`encode_piece`).
        self.memo: PieceMemo | None = None
        self.candidate = Candidate(
            wavelet_coefficients(self.coded, options.wavelet, plan.levels, options.extension),
            plan.levels,
            lifting_levels_for(options, plan.levels, plan.geometry),
        )
        magnitudes = np.abs(np.concatenate([c.ravel() for c in self.candidate.coefficients]))
        # Above every coefficient, within the thresholds a file may hold: an image of zeros (or of
        # values below MIN_THRESHOLD) is coded at MIN_THRESHOLD, as zeros; values too large for
        # MAX_THRESHOLD are refused by the quantizer.
        t_max = 2.0 * float(magnitudes.max()) * max(1.0, plan.geometry.get("normal_weight", 1.0))
        self.t_max = min(max(t_max, MIN_THRESHOLD), MAX_THRESHOLD)
        # A rate target's model keeps a sample of the magnitudes, not all of them.
        self.model = ratecontrol.size_model(magnitudes) if bpp is not None else None
        del magnitudes
        layout_xy = plan.layout == Layout.XY
        self.reference = x[..., 0] if x.shape[2] == 1 else x[..., :2] if layout_xy else x
        # A quality target's search starts where a uniform quantizer's error would meet it.
        self.t_guess = None
        if max_angle is not None:
            self.t_guess = min(self.t_max, np.radians(max_angle))
        elif psnr is not None:
            top = metrics.peak(self.reference, options.kind)
            self.t_guess = min(self.t_max, 2.0 * top * 10 ** (-psnr / 20)) or self.t_max / 1e3
        targeted = (bpp, threshold, self.t_guess) != (None,) * 3
        self.choosing_levels = options.kind == Kind.NORMAL_MAP and options.wavelet == "cdf97" and targeted
        self.quality_target = psnr is not None or max_angle is not None
        #: The runner-up count of levels, if close, for a rate target to try.
        self.level_trial: list[int] = []
        if self.choosing_levels:
            self._choose_levels(bpp, threshold)

    def _choose_levels(self, bpp, threshold) -> None:
        """Fewer levels where the median predictor codes the coarse band for less (levelchoice), at
        the threshold expected: the first of rate control or of a quality target's search."""
        t = self.t_guess
        if threshold is not None:
            t = float(threshold)
        elif bpp is not None:
            t = ratecontrol.first_threshold(self._target_bytes(bpp), self.t_max, self.model)
        levels = self.candidate.levels
        fewer, *self.level_trial = levels_to_try(
            self.candidate.coefficients, levels, t, frames=not self.plan.two_channels
        )
        if fewer < levels:
            options = self.options
            self.candidate = Candidate(
                wavelet_coefficients(self.coded, options.wavelet, fewer, options.extension),
                fewer,
                lifting_levels_for(options, fewer, self.plan.geometry),
            )
            if self.model is not None:
                magnitudes = np.abs(np.concatenate([c.ravel() for c in self.candidate.coefficients]))
                self.model = ratecontrol.size_model(magnitudes)

    def _target_bytes(self, bpp: float) -> int:
        return int(bpp * self.plan.height * self.plan.width / 8)

    def choose(
        self, t: float | None, tries: bool = False, target: int = 0
    ) -> tuple[Candidate, list[Candidate]]:
        """The candidate coded, chosen for the threshold ``t`` (None: as it is), and those a rate
        target tries too (``tries``): lifted along directions where they pay (or nearly), the runner-up
        count of levels, the Riesz pair where it pays (or nearly); below effort
        :data:`FULL_TRIALS_FROM`, the one of them that promises most at ``target`` bytes
        (:meth:`_cheapest`) is the candidate, and none is left to try. Then the measures are made, and
        the source is let go of where it is not measured again (one large array at a time: the
        peak of large images)."""
        plan, options, candidate = self.plan, self.options, self.candidate
        tries = tries and plan.height * plan.width <= TRIAL_PIXELS and options.effort >= TRIALS_FROM
        trials: list[Candidate] = []
        if candidate.lifting_levels and t is not None:
            # A tile's later pass takes the directions of its first (bandelets.codec.piecememo).
            reused = None if self.memo is None else self.memo.lifted(
                self.coded, candidate.coefficients, candidate.levels, t
            )  # fmt: skip
            coefficients, fields, lifting_levels, trial = (*reused, None) if reused else lifted(
                self.coded, candidate.coefficients, candidate.levels, candidate.lifting_levels, t,
                options.lifting is None,
            )  # fmt: skip
            if self.memo is not None and not reused:
                self.memo.keep(t, candidate.levels, lifting_levels, fields)
            candidate = Candidate(coefficients, candidate.levels, lifting_levels, fields)
            if trial is not None and tries:
                trials.append(Candidate(trial[0], candidate.levels, trial[2], trial[1]))
        if self.level_trial and tries:
            levels = self.level_trial[0]
            coefficients, fields, lifting_levels = with_levels(self.coded, levels, t, options, plan.geometry)
            trials.append(Candidate(coefficients, levels, lifting_levels, fields))
        if plan.pairable and t is not None:
            sign, pair, levels, ratio = riesz_pair(
                self.coded, candidate.coefficients, candidate.lifting, candidate.lifting_levels,
                candidate.levels, t, options, choose=self.choosing_levels,
            )  # fmt: skip
            if ratio < RIESZ_PAYS_BELOW:
                candidate, trials = Candidate(pair, levels, turn=sign), []
                self.t_max = raised_t_max(pair, self.t_max)
            elif ratio < RIESZ_TRIAL_BELOW and tries:
                trials.append(Candidate(pair, levels, turn=sign))
            del pair
        coded, self.coded = self.coded, None
        # A loop per alternative compares restored files: without the restoration and the loop
        # filter, the least cost at one threshold decides at every effort.
        looped = options.effort >= FULL_TRIALS_FROM and (options.restore or options.loop_filter)
        if trials and t is not None and target > 0 and not looped:
            candidate, trials = self._cheapest(candidate, trials, t, target), []
        self.candidate = candidate
        self._make_measures(coded)
        return candidate, trials

    def _cheapest(self, candidate: Candidate, trials: list[Candidate], t: float, target: int) -> Candidate:
        """Of ``candidate`` and its ``trials``, the one whose wavelet files promise the best PSNR at
        ``target`` bytes: each coded at ``t`` and at a second threshold on the target's other side,
        decoded without the restoration, its PSNR interpolated in log size (four wavelet files and
        decodes of 512 x 512 take about the time of one bandelet encode; a rate-control loop per
        alternative, restored, takes 0.8 to 1.2 s). Effort 8 keeps the loops (``benchmarks/effort.py
        --all`` compares the two)."""
        first: dict[int, Encoded] = {}

        def promised(choice: Candidate) -> float:
            near = first[id(choice)] = self.encode_at(choice, t, "wavelet")
            # A threshold 30 % away, on the target's other side: an interpolation, not a guess.
            other = self.encode_at(choice, t * (1.3 if len(near.data) > target else 1 / 1.3), "wavelet")
            points = [(math.log(len(e.data)), self.measure(self.unrestored(e))) for e in (near, other)]
            (x0, y0), (x1, y1) = points
            return y0 if x0 == x1 else y0 + (y1 - y0) * (math.log(target) - x0) / (x1 - x0)

        choices = [candidate, *trials]
        self._measurer()  # the reference copied once, before the threads share it
        # The alternatives in threads (the coder's and the transforms' kernels let go of the GIL):
        # on two cores, the weighing's wall time nearly halves.
        promises = list(thread_map(promised, choices, min(CORES, len(choices))))
        best = choices[promises.index(max(promises))]
        # Rate control's probe is often this very file (its first threshold is ``t``).
        self.probed = (t, first[id(best)])
        if best.turn and not candidate.turn:
            self.t_max = raised_t_max(best.coefficients, self.t_max)
        return best

    def _make_measures(self, coded: np.ndarray) -> None:
        """The measures, ``coded`` the channels coded (:func:`bandelets.codec.plan.plan_image`)."""
        plan, options, reference, kind = self.plan, self.options, self.reference, self.options.kind
        if options.restore or options.loop_filter:  # what the user gets: the values written at its depth
            self.measures.channels = metrics.psnr_of_channels(reference, kind, plan.depth, plan.equidistant)
        if options.loop_filter:  # what the coded channels stand for, and the error of a PSNR
            planes = (
                coded  # the equidistant coordinates of the reference: not made again
                if plan.equidistant
                else normals.with_z(reference)  # x, y coded with their z (box mips)
                if reference.ndim == 3 and reference.shape[-1] < plan.channels
                else reference.reshape(plan.height, plan.width, -1)
            )
            self.measures.planes = np.ascontiguousarray(
                np.moveaxis(planes[..., : plan.channels], -1, 0), np.float32
            )
            self.measures.to_error = partial(
                squared_error_of,
                peak=metrics.peak(reference, kind),
                samples=plan.height * plan.width * (3 if kind == Kind.NORMAL_MAP else plan.channels),
            )
        # Rate control holds the source only where it measures a decoded image against it: a
        # quality target, or a measured encode without the restoration.
        if not (self.quality_target or (self.measured and not options.restore)):
            self.reference = self._psnr = None

    def encode_at(
        self, candidate: Candidate, t: float, transform: str | None = None, search=best_trees
    ) -> Encoded:
        """The file of ``candidate`` at the threshold ``t`` (``transform``: the options' if None;
        ``search``: of the quadtrees, see :func:`bandelets.codec.at_threshold.encode_at_threshold`)."""
        plan, options = self.plan, self.options
        header = Header(
            height=plan.height,
            width=plan.width,
            channels=plan.channels,
            kind=options.kind,
            transform=transform or options.transform,
            wavelet=options.wavelet,
            levels=candidate.levels,
            threshold=max(t, MIN_THRESHOLD),  # rate control's exp(log T) may round below it
            depth=plan.depth,
            transform_1d=options.transform_1d,
            **plan.geometry,
            layout=plan.layout,
            lifting=candidate.lifting_levels,
            folded=plan.folded,
            riesz=candidate.turn,
        )
        return encode_at_threshold(candidate.coefficients, header, candidate.lifting, search)

    def finish(self, encoded: Encoded, budget: int | None = None) -> Encoded:
        """``encoded`` with the restoration and the loop filter chosen (the filter within ``budget``
        bytes of the whole file), or measured (``measured``); without what only that needed."""
        options, measures = self.options, self.measures
        if options.restore or options.loop_filter:
            encoded, channels = with_restoration(
                encoded, measures.channels, options, self.line, self.keep and not options.loop_filter
            )
            if options.loop_filter:
                room = None if budget is None else budget - len(encoded.data)
                encoded = with_loop_filter(
                    encoded, channels, measures.planes, measures.channels, measures.to_error, room, self.keep
                )
        elif self.measured:
            out = self.decoded(encoded)
            encoded = replace(encoded, psnr=self.measure(out), decoded=out)
        # Only the restoration's choice needed the trees and bins; the decoded image is kept for
        # the caller (measured) or the angular target, not held through rate control.
        return replace(
            encoded, trees=None, bins=None, lifting=None, decoded=encoded.decoded if self.keep else None
        )

    def decoded(self, encoded: Encoded) -> np.ndarray:
        """What :func:`bandelets.decode` returns for ``encoded`` (through the decoder's own entry)."""
        if encoded.decoded is not None:  # the restored image, as decode returns it
            return encoded.decoded
        header, streams = unpack(encoded.data, **OWN_FILE)
        return decode_parsed(
            header, streams, max_memory=self.options.max_memory, max_work=self.options.max_work
        )

    def unrestored(self, encoded: Encoded) -> np.ndarray:
        """What :func:`bandelets.decode` returns for ``encoded`` without the restoration and the loop
        filter, made from the bins the encoder coded (the decoder's own steps after its range
        decoding, which this skips)."""
        header = replace(encoded.header, restoration=0, loop_filter=None)
        return decoded_from_bins(header, encoded.trees, encoded.bins, encoded.lifting)

    def _measurer(self):
        """The PSNR against the source (:func:`bandelets.metrics.psnr_against`: its reference copied
        once, when first needed)."""
        if self._psnr is None:
            self._psnr = metrics.psnr_against(self.reference, self.options.kind)
        return self._psnr

    def measure(self, decoded: np.ndarray) -> float:
        """PSNR of a decoded image as written at the source's depth."""
        return self._measurer()(as_read(decoded, self.options.kind, self.plan.depth))

    def for_size(self, bpp: float) -> Encoded:
        """The best file of at most ``bpp`` bits per pixel: rate control on the candidate chosen
        (:meth:`choose`), then, from effort :data:`FULL_TRIALS_FROM`, on each one close to paying,
        the better file kept."""
        options = self.options
        target = self._target_bytes(bpp)
        if target < HEADER_BYTES:
            raise ValueError(
                f"target of {bpp:g} bpp ({target} bytes) cannot be reached: a .bdl file needs at "
                f"least {HEADER_BYTES} bytes of header"
            )
        # Room is left for the loop filter's bytes (what the file does not take of it is lost).
        room = loopfilter.reserve(self.plan.channels) if options.loop_filter else 0
        aimed = self.candidate.lifting_levels or self.plan.pairable
        first = ratecontrol.first_threshold(target - room, self.t_max, self.model) if aimed else None
        candidate, trials = self.choose(first, tries=True, target=target - room)
        model = self.model
        if candidate.lifting is not None or candidate.turn:
            model = _lifted_model(candidate)
        kept = self._search_size(candidate, bpp, target, room, model)
        for trial in trials:
            if kept.psnr is None:
                break
            # Directions or a Riesz pair close to paying: that file too, the better kept.
            if trial.turn:
                self.t_max = raised_t_max(trial.coefficients, self.t_max)
            other = self._search_size(trial, bpp, target, room, _lifted_model(trial))
            kept = other if other.psnr > kept.psnr else kept
        return kept

    def _search_size(self, candidate: Candidate, bpp: float, target: int, room: int, model) -> Encoded:
        # The loop's later encodes reuse the geometry of its first (bandelets.search.treememo).
        encode_at = partial(self.encode_at, candidate, search=TreeMemo().search)
        # A wavelet file aims the first encoding (none where it would be the file itself).
        plain = partial(self._wavelet_file, candidate)  # the probe's: no geometry to reuse
        probe = None if self.options.transform == "wavelet" else partial(_probe, plain, bpp)
        found = ratecontrol.for_size(
            encode_at,
            target,
            self.t_max,
            model,
            progress=self.line,
            t_min=MIN_THRESHOLD,
            room=room,
            probe=probe,
        )
        return self.finish(found, budget=target)

    def _wavelet_file(self, candidate: Candidate, t: float, transform: str) -> Encoded:
        """The wavelet file of ``candidate`` at ``t``: the one :meth:`_cheapest` made, if at ``t``."""
        if self.probed is not None and math.isclose(self.probed[0], t, rel_tol=1e-9):
            return self.probed[1]
        return self.encode_at(candidate, t, transform)

    def for_quality(self, *, psnr: float | None, max_angle: float | None) -> Encoded:
        """The smallest file whose restored image meets a PSNR or a p99 angular error."""
        options = self.options
        if max_angle is not None:
            # -20 log10 of the angle falls with log T like a PSNR: the same search applies.
            goal = -20.0 * np.log10(max_angle)

            def quality(encoded: Encoded) -> float:
                decoded = as_read(self.decoded(encoded), options.kind, self.plan.depth)
                p99 = metrics.angular_error(self.reference, decoded).p99
                return -20.0 * np.log10(max(p99, 1e-12))

            def label(q: float) -> str:
                return f"p99 angle of {10 ** (-q / 20):.3g} degrees"
        else:
            goal = float(psnr)

            def quality(encoded: Encoded) -> float:
                return encoded.psnr if encoded.psnr is not None else self.measure(self.decoded(encoded))

            def label(q: float) -> str:
                return f"PSNR of {q:.2f} dB"

        candidate, _ = self.choose(self.t_guess)
        # Each try is restored: the target is met by the restored image, with the smallest file.
        return ratecontrol.for_quality(
            lambda t: self.finish(self.encode_at(candidate, t)),
            quality,
            goal,
            self.t_max,
            self.t_guess,
            progress=self.line,
            label=label,
            t_min=MIN_THRESHOLD,
        )


def _lifted_model(candidate: Candidate):
    """The size model of a lifted file or a Riesz pair: it follows a model of their own coefficients
    better (the pair codes' flat blocks): as many encodings as before them, not one more at 0.7 to
    2 bpp on the crease maps. A regular sample (odd step) keeps the sort short."""
    coefficients = np.concatenate([c.ravel() for c in candidate.coefficients])
    return ratecontrol.size_model(np.abs(coefficients[::3]), coefficients.size)


def _probe(encode_at, bpp: float, t: float) -> float:
    """The size of the file ``encode_at`` makes at ``t`` predicted from that of the wavelet file
    (every square NULL: 0.13 to 0.2 of the time of the bandelet file at 256 and 512 pixels a side,
    slightly smaller; see :data:`PROBE_BIAS`)."""
    return len(encode_at(t, "wavelet").data) * math.exp(PROBE_BIAS / bpp)


def _read_back(encoded: Encoded) -> Encoded:
    """``encoded`` with the header, quadtrees, bins and directions its file holds, as the decoder
    reads them, and without its loop filter (fitted to the unrestored image: chosen again)."""
    header, streams = unpack(encoded.data, **OWN_FILE)
    trees, bins, lifting = decoded_bins(header, streams)
    header = replace(header, loop_filter=None)
    data = pack(header, streams)
    return replace(encoded, data=data, header=header, trees=trees, bins=bins, lifting=lifting)
