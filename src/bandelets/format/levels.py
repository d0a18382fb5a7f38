"""The streams of a .bdl file stored level by level (format version 19), so that a prefix of the file
decodes at a coarser level.

The encoder cuts each of the three range-coded streams (splits, directions, coefficients) after the
coarse approximation and after each wavelet level's three subbands (:func:`bandelets.coding.image.
code_image`; the arithmetic state restarts, the adaptive contexts go on), and the file stores the
segments group by group: the approximation's (group 0), then those of the coarsest detail level
(group 1), ..., the finest (group ``levels``), each group its splits, directions and coefficients
segments in that order. The header holds the byte length of every segment (LEB128, group by group)
but the two of group 0 that are always empty (the approximation has no quadtree nor directions). A
lossless file has one group (:mod:`bandelets.coding.lossless` codes no levels).

The image at level ``k`` (``1 / 2**k`` of the size) needs groups ``0`` to ``levels - k``: a file cut
after them decodes there (:func:`bandelets.codec.levels.decode_level`).
"""

from __future__ import annotations

from .fields import LOSSLESS

__all__ = ["group_count", "groups_for", "interleave", "parts", "segment_lengths", "split", "stored_lengths"]


def group_count(levels: int, transform: str | None) -> int:
    """Groups of segments of a file of ``levels`` wavelet levels and ``transform``."""
    return 1 if transform == LOSSLESS else max(levels, 0) + 1


def groups_for(level: int, levels: int) -> int:
    """Groups the image at ``level`` needs (the coarse approximation alone from ``levels`` on)."""
    return levels - min(level, levels) + 1


def interleave(streams: tuple[bytes, bytes, bytes], segments: tuple[tuple[int, int, int], ...]) -> bytes:
    """The bytes of the three ``streams`` group by group, each cut by the ``segments`` lengths."""
    starts, out = [0, 0, 0], []
    for group in segments:
        for s, n in enumerate(group):
            out.append(streams[s][starts[s] : starts[s] + n])
            starts[s] += n
    return b"".join(out)


def split(data: bytes, start: int, segments: tuple[tuple[int, int, int], ...]) -> tuple[list[bytes], ...]:
    """The segments of each stream, from the group-by-group bytes of ``data`` at ``start``, as many
    groups as ``data`` holds in whole."""
    out: tuple[list[bytes], ...] = ([], [], [])
    for group in segments:
        if start + sum(group) > len(data):
            break
        for s, n in enumerate(group):
            out[s].append(bytes(data[start : start + n]))
            start += n
    return out


def segment_lengths(
    levels: int, transform: str, segments: tuple, streams: tuple[bytes, bytes, bytes]
) -> tuple[tuple[int, int, int], ...]:
    """The segment lengths a file of ``streams`` stores: ``segments`` (a header's), checked against
    the streams; none given: every byte in the last group."""
    groups = group_count(levels, transform)
    segments = segments or ((0, 0, 0),) * (groups - 1) + (tuple(map(len, streams)),)
    if len(segments) != groups or any(sum(g[s] for g in segments) != len(streams[s]) for s in range(3)):
        raise ValueError(f"segments {segments} do not cut streams of {tuple(map(len, streams))} bytes")
    return tuple(tuple(int(n) for n in g) for g in segments)


def parts(streams: tuple[bytes, bytes, bytes], segments: tuple) -> tuple[list[bytes], ...]:
    """The segments of each of the three whole ``streams`` (what a decoder reads, group by group)."""
    if not segments:
        return tuple([s] for s in streams)
    out: tuple[list[bytes], ...] = ([], [], [])
    for s, stream in enumerate(streams):
        start = 0
        for group in segments:
            out[s].append(stream[start : start + group[s]])
            start += group[s]
    return out


def stored_lengths(segments: tuple) -> list[int]:
    """The segment lengths a header stores: all but group 0's splits and directions (empty)."""
    if segments[0][:2] != (0, 0):
        raise ValueError(f"segments {segments}: the approximation's group has splits or directions")
    return [segments[0][2]] + [n for group in segments[1:] for n in group]
