"""Encoding of an image in tiles (:mod:`bandelets.format.container`): every tile coded as one piece
(:mod:`bandelets.codec.piece`) at one threshold, found by one search on the whole file's size or
quality, at most :data:`~bandelets.format.container.WORKERS` tiles in flight.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import metrics
from ..format.container import TILE_WORK, WORKERS, Grid, pack
from ..format.fields import MAX_THRESHOLD, MIN_THRESHOLD, Kind, Layout
from ..format.header import HEADER_BYTES
from ..format.limits import check_encodable, tile_side
from ..format.samples import as_read
from ..runtime.progress import Progress
from ..runtime.threads import thread_map
from ..search import ratecontrol
from ..transform.bandelets import wavelet_coefficients
from ..transform.normals import unit_vectors, with_z
from ..transform.wavelets import max_levels
from . import normalmaps
from .at_threshold import Encoded
from .piece import encode_piece
from .piecememo import PieceMemo

__all__ = ["encode_tiles", "side", "tiled"]


@dataclass
class _Tile:
    """One tile coded at a threshold, and what the encoder measured of it."""

    data: bytes
    coefficient_sse: float
    sse: float = 0.0  # squared error of the decoded tile as :func:`bandelets.metrics.psnr` counts it
    samples: int = 0
    extremes: np.ndarray | None = None  # (2, C): the least and the largest value of each channel
    angles: np.ndarray | None = None  # angular error of each pixel, degrees, float32 (normal maps)


def encode_tiles(array, options, *, bpp=None, threshold=None, psnr=None, max_angle=None, measured=False):
    """:func:`bandelets.codec.encoder.encode_with_stats` for an image of more than one tile
    (:func:`side`): every tile coded at one threshold, found by one search on the whole file's
    size or quality, at most :data:`WORKERS` tiles in flight.

    The returned :class:`~bandelets.codec.encoder.Encoded` holds the PSNR of the whole decoded image (and
    for a normal map its angular error) when ``measured``, but not the decoded image itself.
    """

    source = np.asarray(array)
    grid = Grid(source.shape[0], source.shape[1], side(source, options))
    check_encodable(
        grid.height, grid.width, source.shape[2] if source.ndim == 3 else 1, options.max_memory, grid.tile
    )
    fixed = len(grid.boxes) * TILE_WORK  # what the decoder counts for the tiles (TILE_WORK)
    if fixed > options.max_work:
        raise ValueError(
            f"{len(grid.boxes)} tiles of {grid.tile} are {fixed:.3g} units of work to decode, above the "
            f"limit of {options.max_work:.3g} (max_work): choose larger tiles"
        )
    kind = options.kind

    with Progress(options.progress) as line:
        # The tiles of each pass without restoration (their bytes): the last pass restores and
        # measures those of its threshold rather than coding them again.
        passes: dict[float, list[_Tile]] = {}
        # Each tile's directions and geometry of its first pass, for its later ones (piecememo).
        memos = [PieceMemo() for _ in grid.boxes]

        def encode_at(t: float, restore: bool, keep: bool) -> Encoded:
            line.stage(f"pass {len(passes) + 1}, T={t:.3g}: tiles", restart=True)
            t = max(t, MIN_THRESHOLD)
            earlier = passes.get(t) if restore or keep else None

            def one(item):
                box, unrestored, memo = item
                return _coded_tile(source, box, grid, options, t, restore, keep, unrestored, memo)

            tiles = []
            for tile in thread_map(
                one, zip(grid.boxes, earlier or [None] * len(grid.boxes), memos, strict=True), WORKERS
            ):
                tiles.append(tile)
                line.step()
            if not (restore or keep):
                passes[t] = [_Tile(tile.data, tile.coefficient_sse) for tile in tiles]
            data = pack(grid, [tile.data for tile in tiles])
            result = Encoded(data, t, sum(tile.coefficient_sse for tile in tiles))
            if not keep:
                return result
            return _with_measures(result, tiles, kind)

        if threshold is not None:
            return encode_at(float(threshold), options.restore, measured)
        magnitudes, count, t_max, top = _coefficient_sample(source, grid, options)
        t_max = min(max(t_max, MIN_THRESHOLD), MAX_THRESHOLD)
        if bpp is not None:
            target = int(bpp * grid.height * grid.width / 8)
            if target < HEADER_BYTES:
                raise ValueError(f"target of {bpp:g} bpp ({target} bytes) cannot be reached")
            model = ratecontrol.size_model(magnitudes, count)
            best = ratecontrol.for_size(
                lambda t: encode_at(t, False, False), target, t_max, model, t_min=MIN_THRESHOLD
            )
            if options.restore or measured:  # the same tiles, restored and measured
                best = encode_at(best.threshold, options.restore, measured)
            return best
        if max_angle is not None:
            goal, t_guess = -20.0 * np.log10(max_angle), min(t_max, np.radians(max_angle))

            def quality(encoded) -> float:
                return -20.0 * np.log10(max(encoded.angles.p99, 1e-12))

            def label(q: float) -> str:
                return f"p99 angle of {10 ** (-q / 20):.3g} degrees"
        else:
            goal, t_guess = float(psnr), min(t_max, 2.0 * top * 10 ** (-psnr / 20)) or t_max / 1e3

            def quality(encoded) -> float:
                return encoded.psnr

            def label(q: float) -> str:
                return f"PSNR of {q:.2f} dB"

        return ratecontrol.for_quality(
            lambda t: encode_at(t, options.restore, True),
            quality,
            goal,
            t_max,
            t_guess,
            label=label,
            t_min=MIN_THRESHOLD,
        )


def _coded_tile(
    source: np.ndarray,
    box,
    grid: Grid,
    options,
    t: float,
    restore: bool,
    keep: bool,
    unrestored: _Tile | None,
    memo: PieceMemo | None = None,
) -> _Tile:
    """The tile ``box`` of ``source`` coded at ``t`` as one piece (``unrestored``: its file without
    restoration, only restored again; ``memo``: its choices at a nearby threshold), measured when
    ``keep``."""
    kind = options.kind
    # No loop filter: its bytes would come after the search of the threshold of every tile.
    tile_options = replace(options, progress=False, tile=grid.tile, loop_filter=False)
    tile = source[box]
    earlier = None if unrestored is None else Encoded(unrestored.data, t, unrestored.coefficient_sse)
    # Each tile's share of max_work, by its pixels: the restoration of the whole file is bounded
    # as that of one piece is (and as the decoder checks it), not max_work once per tile.
    # max_work less the tiles' fixed work, as the decoder counts it (TILE_WORK).
    left = options.max_work - len(grid.boxes) * TILE_WORK
    share = left * tile.shape[0] * tile.shape[1] // (grid.height * grid.width)
    encoded = encode_piece(
        tile,
        replace(tile_options, restore=restore, max_work=share),
        threshold=t,
        measured=keep,
        unrestored=earlier,
        memo=memo,
    )
    out = _Tile(encoded.data, encoded.coefficient_sse)
    if keep:
        reference, depth = _reference(tile, options)
        decoded = np.asarray(as_read(encoded.decoded, kind, depth)).reshape(reference.shape)
        out.sse, out.samples, out.extremes = _squared_error(reference, decoded, kind)
        if kind == Kind.NORMAL_MAP:
            out.angles = metrics.angles(reference, decoded).astype(np.float32)
    return out


def _with_measures(result: Encoded, tiles: list[_Tile], kind: str) -> Encoded:
    """``result`` with the PSNR (and a normal map's angular error) of the whole image, from its tiles'."""
    sse, samples = sum(tile.sse for tile in tiles), sum(tile.samples for tile in tiles)
    top = metrics.peak(np.concatenate([tile.extremes for tile in tiles]), kind)
    result = replace(result, psnr=float("inf") if sse == 0 else 20.0 * np.log10(top / np.sqrt(sse / samples)))
    if kind == Kind.NORMAL_MAP:
        angles = np.concatenate([tile.angles for tile in tiles])
        result = replace(
            result,
            angles=metrics.AngularError(
                float(angles.mean(dtype=np.float64)),
                float(np.percentile(angles, 99)),
                float(angles.max()),
            ),
        )
    return result


def _reference(tile: np.ndarray, options) -> tuple[np.ndarray, int]:
    """What the encoder measures a decoded tile against (as :func:`bandelets.codec.encoder.encode_with_stats`
    does: a normal map as unit vectors, ``x, y`` alone for that layout), and the source's depth."""

    if options.kind != Kind.NORMAL_MAP:
        return np.asarray(tile, np.float64), options.depth
    x, depth, layout = normalmaps.prepare(tile, options.depth, options.xy)
    x = unit_vectors(np.asarray(x, np.float64))
    return (x[..., :2] if layout == Layout.XY else x), depth


def _compared(reference: np.ndarray, kind: str) -> np.ndarray:
    """``reference`` as :func:`bandelets.metrics.psnr_against` compares it."""

    if kind == Kind.NORMAL_MAP:
        return unit_vectors(with_z(reference) if reference.shape[-1] == 2 else reference)
    return reference


def _extremes(compared: np.ndarray) -> np.ndarray:
    """(2, C): the least and the largest value of each channel, from which
    :func:`bandelets.metrics.peak` of the whole image follows."""
    flat = compared.reshape(-1, compared.shape[-1] if compared.ndim == 3 else 1)
    return np.stack([flat.min(axis=0), flat.max(axis=0)])


def _squared_error(reference: np.ndarray, decoded: np.ndarray, kind: str) -> tuple[float, int, np.ndarray]:
    """Squared error of ``decoded`` summed as :func:`bandelets.metrics.psnr` sums it, the samples it
    is averaged over, and :func:`_extremes` of the reference."""

    compared = _compared(reference, kind)
    if kind == Kind.NORMAL_MAP and reference.shape[-1] == 2:
        decoded = with_z(decoded)
    return (
        float(np.sum((compared - decoded.reshape(compared.shape)) ** 2)),
        compared.size,
        _extremes(compared),
    )


#: Coefficients the size model of rate control samples (:func:`bandelets.search.ratecontrol.size_model`).
_MODEL_SAMPLES = 2**20


def _coefficient_sample(source: np.ndarray, grid: Grid, options) -> tuple[np.ndarray, int, float, float]:
    """A regular sample of the magnitudes of the tiles' wavelet coefficients (the channels the
    encoder codes, before any local frames), their count, a threshold above all of them (the
    encoder's ``t_max``) and the peak of the whole image's PSNR."""

    samples, count, largest, extremes = [], 0, 0.0, []
    step = max(1, source.size // _MODEL_SAMPLES) | 1
    for box in grid.boxes:
        reference, _ = _reference(source[box], options)
        compared = _compared(reference, options.kind)
        extremes.append(_extremes(compared))
        channels = compared if compared.ndim == 3 else compared[..., None]
        if options.kind == Kind.NORMAL_MAP and np.all(channels[..., 2] >= 0):
            channels = channels[..., :2]
        coefficients = wavelet_coefficients(
            channels, options.wavelet, max_levels(channels.shape[:2]), options.extension
        )
        magnitudes = np.abs(np.concatenate([c.ravel() for c in coefficients]))
        samples.append(magnitudes[::step].copy())  # a view would hold every tile's coefficients
        count += magnitudes.size
        largest = max(largest, float(magnitudes.max()))
    weight = options.normal_weight if options.frames else 1.0
    top = metrics.peak(np.concatenate(extremes), options.kind)
    return np.concatenate(samples), count, 2.0 * largest * max(1.0, weight), top


def side(array, options) -> int:
    """The tile side :func:`bandelets.encode` codes ``array`` with (0: one piece; see ``tile``
    there and :func:`bandelets.format.limits.tile_side`): one piece for the spherical extension (a
    spherical geometry image folds its borders onto each other)."""

    shape = np.shape(array)
    if len(shape) not in (2, 3) or options.extension != "symmetric":
        return 0
    return tile_side(*shape[:2], shape[2] if len(shape) == 3 else 1, options.tile, options.max_memory)


def tiled(array, options) -> bool:
    """Whether :func:`bandelets.encode` codes ``array`` in more than one tile (:func:`side`)."""
    tile = side(array, options)
    return bool(tile) and Grid(*np.shape(array)[:2], tile).tiled
