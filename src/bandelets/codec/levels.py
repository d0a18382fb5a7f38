"""Decoding at a coarser level, from a prefix of a file (format version 19).

``decode(data, level=k)`` returns the image at ``1 / 2**k`` of the size (each side ``ceil(side /
2**k)``): the coarse approximation of the 2D wavelet transform, from the groups of segments that
hold the approximation and the detail levels coarser than ``k`` (:mod:`bandelets.format.levels`),
which are the first bytes of the file. The inverse transform stops ``k`` levels early
(:func:`bandelets.transform.coarse.coarse`), filtered to the box averages of the image it
synthesises (:func:`bandelets.transform.coarse.box_filtered`: a mip), with the directions of the
lifted levels it inverts, the local frames of the levels it reads and the Riesz pair turned back
on the coarse grid (the angle of a frequency is the same on both grids); a normal map's vectors
are renormalised. No loop filter (it is fitted to the full image) and no restoration, but for a
file of a box wavelet (``encode(box_mips=True)``), whose level images are its box mips themselves,
restored (:mod:`bandelets.codec.boxlevels`). Beyond the file's wavelet levels, the coarse
approximation is halved by 2 x 2 box averages (renormalised for a normal map).

Tiled files: each tile is decoded at level ``k`` and the tiles are placed side by side; a tile of
``h x w`` pixels gives ``ceil(h / 2**k) x ceil(w / 2**k)``, so the image is ``ceil(side / 2**k)``
when the tile side is a multiple of ``2**k`` (the default 512 is, up to ``k = 9``). A prefix of a
tiled file does not decode (its tiles are one after the other): read it whole, or each tile's first
bytes (:func:`level_bytes` sums them).
"""

from __future__ import annotations

import struct
from dataclasses import replace

import numpy as np

from ..coding import rangecoder
from ..coding.image import code_image, new_coders
from ..format.container import _HEAD, header_of, is_tiled, read
from ..format.fields import LOSSLESS, MAX_MEMORY, MAX_WORK, FormatError, Kind, Layout, padded_shape
from ..format.header import HEADER_BYTES, Header, streams_offset, unpack_prefix
from ..format.levels import group_count, groups_for
from ..format.limits import check_memory, check_work
from ..format.quantizer import dequantize
from ..transform import frames, riesz
from ..transform.bandeletize import debandeletize
from ..transform.bandelets import apply_trees
from ..transform.coarse import box_filtered, coarse
from ..transform.normals import unit_normals
from .boxlevels import box_level, has_box_levels

__all__ = ["decode_level", "level_bytes", "level_shape", "prefix_header"]


def level_shape(height: int, width: int, level: int) -> tuple[int, int]:
    """The size of the image at ``level``: each side divided by ``2**level``, rounded up."""
    return -(-height >> level), -(-width >> level)


def decode_level(
    data: bytes,
    level: int,
    max_memory: int = MAX_MEMORY,
    restore: bool = True,
    max_work: int = MAX_WORK,
    **limits,
) -> np.ndarray:
    """The image of the file (or a prefix of it) ``data`` at ``level`` (see the module; ``max_memory``,
    ``restore``, ``max_work`` and ``limits``, ``max_side`` and ``max_samples``: as
    :func:`bandelets.decode`, for each tile of a tiled file), shaped as :func:`bandelets.decode`
    returns it."""
    if not isinstance(level, (int, np.integer)) or level < 0:
        raise ValueError(f"level must be an integer >= 0, not {level!r}")
    if is_tiled(data):
        return _tiles(data, level, max_memory, restore, max_work, **limits)
    return _prefix_image(data, level, max_memory, restore, max_work, **limits)


def _prefix_image(
    data: bytes, level: int, max_memory: int, restore: bool, max_work: int, **limits
) -> np.ndarray:
    """The image at ``level`` of a plain file, from the bytes it needs alone (no CRC over the rest)."""
    needs = level_bytes(data)
    if level and needs[min(level, len(needs) - 1)] <= len(data):
        data = data[: needs[min(level, len(needs) - 1)]]
    header, segments = unpack_prefix(data, **limits)
    check_memory(replace(header, restoration=0, loop_filter=None), max_memory)  # full-size bins at most
    return level_image(header, segments, level, len(data), data, restore, max_work)


def level_image(
    header: Header,
    segments: tuple,
    level: int,
    size: int = 0,
    data: bytes = b"",
    restore: bool = True,
    max_work: int = MAX_WORK,
) -> np.ndarray:
    """The image at ``level`` of a parsed file: ``segments`` those of each stream it holds (a prefix's
    ``size`` bytes, ``data``: for the message of a refusal; ``restore``, ``max_work``: the restoration
    of a box-mip file's level image, :func:`_box_restoration`)."""
    if header.transform == LOSSLESS:
        raise FormatError("a lossless .bdl file decodes at level 0 only (it codes no wavelet levels)")
    k = min(level, header.levels)
    need = groups_for(k, header.levels)
    if len(segments[0]) < need:
        raise FormatError(
            f"this prefix of {size} bytes does not hold level {level}: it needs the first "
            f"{level_bytes(data)[level] if data else '?'} bytes of the file"
        )
    coders = new_coders(tuple(s[:need] for s in segments))
    try:
        lifting: list = []
        trees, quantized, _ = code_image(coders, header, lifting=lifting, upto=k)
    except rangecoder.CorruptStream as err:
        raise FormatError(f"corrupt .bdl file: {err}") from None
    shape = padded_shape((header.height, header.width), header.levels)
    h, w = shape[0] >> k, shape[1] >> k
    channels = []
    for q in quantized:
        x = dequantize(q.reshape(shape), header.threshold)
        block = np.ascontiguousarray(x[:h, :w])
        x[:h, :w] = apply_trees(block, header.levels - k, trees, debandeletize, header.transform_1d)
        channels.append(x)
    found = {}
    if header.frames:  # back from the local frames, coarsest first (frames.to_global), the levels read
        for lev in range(header.levels, k, -1):
            args = (header.wavelet, header.levels, header.extension)
            found[lev] = frames.level_frames(channels, lev, *args, header.kind)
            frames.rotate(channels, found[lev], lev, header.levels, header.normal_weight, local=False)
    if has_box_levels(header):
        bins = [q.reshape(shape) for q in quantized]
        restored = _box_restoration(header, k, restore, max_work)
        small = box_level(restored, trees, bins, [x[:h, :w] for x in channels], found, k)
    else:
        small = np.stack([_local_means(x, header, k, lifting) for x in channels])
    if header.riesz:
        small[0], small[1] = riesz.inverse(small[0], small[1], header.riesz)
    return _halved(_image(small, header, k), header, level - k)


def _box_restoration(header: Header, k: int, restore: bool, max_work: int) -> Header:
    """``header`` with the restoration of its level-``k`` image: none without ``restore``; the
    file's iterations, refused (:func:`bandelets.format.limits.check_work`) above ``max_work``."""
    if not restore:
        return replace(header, restoration=0)
    shape = padded_shape((header.height, header.width), header.levels)
    check_work(replace(header, height=shape[0] >> k, width=shape[1] >> k, levels=header.levels - k), max_work)
    return header


def _local_means(x: np.ndarray, header: Header, k: int, lifting: list) -> np.ndarray:
    """The level-``k`` image of the channel of dequantized coefficients ``x`` (overwritten) of a file
    whose wavelet is not a box one: its approximation, filtered towards box averages."""
    means = coarse(x, header.wavelet, header.levels, k, header.extension, header.lifting, lifting or None)
    return box_filtered(means, header.wavelet, k)


def _image(small: np.ndarray, header: Header, k: int) -> np.ndarray:
    """What :func:`bandelets.decode` would return, from the level-``k`` channels ``small``."""
    height, width = level_shape(header.height, header.width, k)
    overflow = FormatError("corrupt .bdl file: the decoded values overflow")
    if header.kind == Kind.NORMAL_MAP:
        out = unit_normals(small, height, width, equidistant=header.layout == Layout.XYZ)
        if out is None:
            raise overflow
        return out[..., :2] if header.layout == Layout.XY else out
    out = np.moveaxis(small[:, :height, :width], 0, -1).astype(np.float64)
    if not np.all(np.isfinite(out)):
        raise overflow
    return out[..., 0] if header.channels == 1 else out


def _halved(image: np.ndarray, header: Header, times: int) -> np.ndarray:
    """``image`` halved ``times`` times by 2 x 2 box averages (the last row or column alone where a side
    is odd), a normal map's vectors renormalised (its x, y returned as it was)."""
    if not times:
        return image
    normal = header.kind == Kind.NORMAL_MAP
    x = image if image.ndim == 3 else image[..., None]
    if normal and x.shape[2] == 2:
        x = np.dstack([x, np.sqrt(np.clip(1 - (x**2).sum(-1), 0, None))])
    for _ in range(times):
        h, w = x.shape[0], x.shape[1]
        x = np.pad(x, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
        x = x.reshape(x.shape[0] // 2, 2, x.shape[1] // 2, 2, -1).mean(axis=(1, 3))
    if normal:
        x = x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-12)
        x = x[..., : image.shape[-1]]
    return x if image.ndim == 3 else x[..., 0]


def prefix_header(data: bytes) -> Header:
    """The header of a .bdl file or of a prefix of one (:func:`bandelets.format.container.header_of` of a
    tiled file, which a prefix does not decode)."""
    if is_tiled(data):
        return header_of(data)
    return unpack_prefix(data[: max(streams_offset(data), HEADER_BYTES)])[0]


def level_bytes(data: bytes) -> list[int]:
    """The bytes of ``data`` (a .bdl file) that the image at each level needs, level 0 (the whole
    file) to the file's wavelet levels (the coarse approximation): a prefix of a plain file; of a
    tiled file, the sum over its tiles of each tile's prefix. A lossless file: its size alone."""
    if is_tiled(data):
        tiles = _tile_bytes(data)
        per = [level_bytes(tile) for tile in tiles]
        table = len(data) - sum(map(len, tiles))  # the container's head and tile lengths
        return [table + sum(p[min(k, len(p) - 1)] for p in per) for k in range(max(len(p) for p in per))]
    start = streams_offset(data)
    header, _ = unpack_prefix(data[: max(start, HEADER_BYTES)])  # the header (of a prefix too)
    sizes = [sum(g) for g in header.segments]
    out = [len(data)]
    if group_count(header.levels, header.transform) > 1:
        out += [start + sum(sizes[: groups_for(k, header.levels)]) for k in range(1, header.levels + 1)]
    return out


def _tile_bytes(data: bytes) -> list[bytes]:
    """The .bdl file of every tile of the tiled file ``data`` (its container checked by
    :func:`bandelets.format.container.read`)."""
    grid, _ = read(data)
    count = len(grid.boxes)
    lengths = struct.unpack_from(f"<{count}I", data, _HEAD.size)
    starts = np.cumsum([_HEAD.size + 4 * count + 4, *lengths])
    return [data[a:b] for a, b in zip(starts[:-1], starts[1:], strict=True)]


def _tiles(data: bytes, level: int, max_memory: int, restore: bool, max_work: int, **limits) -> np.ndarray:
    """The image at ``level`` of a tiled file: every tile's, side by side."""
    grid, _ = read(data, **limits)
    images = []
    for (rows, cols), tile in zip(grid.boxes, _tile_bytes(data), strict=True):
        image = _prefix_image(tile, level, max_memory, restore, max_work, **limits)  # its first bytes alone
        if image.shape[:2] != level_shape(rows.stop - rows.start, cols.stop - cols.start, level):
            raise FormatError(
                f"corrupt .bdl file: a tile of {image.shape[1]} x {image.shape[0]} at level {level}"
            )
        images.append(image)
    rows = [box[0] for box in grid.boxes]
    n_cols = sum(1 for r in rows if r == rows[0])
    grid_rows = [images[i : i + n_cols] for i in range(0, len(images), n_cols)]
    out = np.concatenate([np.concatenate(row, axis=1) for row in grid_rows], axis=0)
    return out
