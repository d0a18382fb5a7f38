"""The loop filter's section of a .bdl file: the filter the decoder applies after the restoration
(:mod:`bandelets.restore.loopfilter`), which the encoder fits (:mod:`bandelets.search.filterfit`).

Format version 11 (the squares since 12), between the streams and the CRC when byte
8 says so::

    0       1     radius of the channel's own taps (1 to MAX_FILTER_RADIUS) + 4 times the
                  radius of the square of cross-channel taps (0 none, 1: 3 x 3, 2: 5 x 5; 2 or
                  3 channels only) + 16 if the own taps fill the square of their radius, not
                  the diamond (the 5 x 5 cross-channel square and the own square since 12)
    1       1     shift: a coefficient is its integer over 2**shift (0 to MAX_FILTER_SHIFT)
    2       1     width: bits of every integer (2 to MAX_FILTER_WIDTH), two's complement
    3       1     clipping of the differences: 0 none, k (1 to MAX_FILTER_CLIP) to +-T 2**(3 - k)
    4       ...   the integers of every channel's taps in turn (:func:`filter_offsets`, then
                  :func:`filter_cross_offsets` of each other channel),
                  most significant bit first, the last byte padded with zeros
"""

from __future__ import annotations

from dataclasses import dataclass

from .fields import (
    MAX_FILTER_CLIP,
    MAX_FILTER_CROSS,
    MAX_FILTER_RADIUS,
    MAX_FILTER_SHIFT,
    MAX_FILTER_WIDTH,
    FormatError,
)

__all__ = [
    "LoopFilter",
    "filter_bytes",
    "filter_cross_offsets",
    "filter_offsets",
    "filter_taps",
    "filter_width",
    "most_filter_bytes",
    "pack_filter",
    "unpack_filter",
]


@dataclass(frozen=True, kw_only=True)
class LoopFilter:
    """The loop filter a file holds (:mod:`bandelets.restore.loopfilter`): the shape of every channel's
    filter and its coefficients, ``coefficients[c * n + t] / 2**shift`` for tap ``t`` of channel
    ``c``."""

    radius: int
    #: Radius of the square of taps on every other channel (0: none, 1: 3 x 3, 2: 5 x 5).
    cross: int
    #: Clipping of the differences: 0 none, ``k`` >= 1 to ``+-T 2**(3 - k)``.
    clip: int
    shift: int
    coefficients: tuple[int, ...]
    #: The channel's own taps fill the square of ``radius``, not the diamond.
    square: bool = False


def filter_offsets(radius: int, square: bool = False) -> tuple[tuple[int, int], ...]:
    """The offsets ``(dy, dx) > (0, 0)`` of the diamond ``|dy| + |dx| <= radius`` (2, 6, 12 for
    radius 1, 2, 3) or of the square ``|dy|, |dx| <= radius`` (4, 12, 24), in row order: one per
    pair of point-symmetric taps of a loop filter."""
    return tuple(
        (dy, dx)
        for dy in range(radius + 1)
        for dx in range(-radius, radius + 1)
        if (square or abs(dy) + abs(dx) <= radius) and (dy, dx) > (0, 0)
    )


def filter_cross_offsets(cross: int) -> tuple[tuple[int, int], ...]:
    """The offsets ``(dy, dx) > (0, 0)`` of the square ``|dy|, |dx| <= cross``, in row order: one
    per pair of point-symmetric taps of a loop filter on every other channel (0, 4, 12 for
    ``cross`` 0, 1, 2)."""
    return filter_offsets(cross, square=True)


def filter_taps(radius: int, cross: int, channels: int, square: bool = False) -> int:
    """Taps of one channel's loop filter: its own (:func:`filter_offsets`), then the other
    channels' (``cross``)."""
    return len(filter_offsets(radius, square)) + len(filter_cross_offsets(cross)) * (channels - 1)


def filter_width(largest: int) -> int:
    """Bits of a two's complement integer that holds ``-largest`` to ``largest`` (at least 2)."""
    return max(int(largest).bit_length() + 1, 2)


def filter_bytes(channels: int, taps: int, width: int) -> int:
    """Bytes of a loop filter section of ``taps`` integers of ``width`` bits per channel."""
    return 4 + (channels * taps * width + 7) // 8


def most_filter_bytes(channels: int) -> int:
    """The largest loop filter section of ``channels`` channels: the 7 x 7 square of own taps, with
    cross-channel taps over the 5 x 5 square for 2 or 3 channels, at MAX_FILTER_WIDTH bits."""
    cross = MAX_FILTER_CROSS if 2 <= channels <= 3 else 0
    return filter_bytes(channels, filter_taps(MAX_FILTER_RADIUS, cross, channels, True), MAX_FILTER_WIDTH)


def pack_filter(loop_filter: LoopFilter, channels: int) -> bytes:
    """The loop filter section (see the module's docstring)."""
    f = loop_filter
    taps = filter_taps(f.radius, f.cross, channels, f.square)
    if not (
        1 <= f.radius <= MAX_FILTER_RADIUS
        and 0 <= f.cross <= MAX_FILTER_CROSS
        and (not f.cross or 2 <= channels <= 3)
        and 0 <= f.shift <= MAX_FILTER_SHIFT
        and 0 <= f.clip <= MAX_FILTER_CLIP
        and len(f.coefficients) == channels * taps
    ):
        raise ValueError(f"not a loop filter of {channels} channels: {f}")
    width = filter_width(max((abs(v) for v in f.coefficients), default=0))
    if width > MAX_FILTER_WIDTH:
        raise ValueError(f"loop filter coefficients of more than {MAX_FILTER_WIDTH} bits: {f}")
    bits = "".join(format(v & ((1 << width) - 1), f"0{width}b") for v in f.coefficients)
    bits += "0" * (-len(bits) % 8)
    return bytes([f.radius + 4 * f.cross + 16 * f.square, f.shift, width, f.clip]) + int(
        bits or "0", 2
    ).to_bytes(len(bits) // 8, "big")


def unpack_filter(section: bytes, channels: int) -> LoopFilter:
    """The validated loop filter of a section (:class:`FormatError` when it is not one)."""
    if len(section) < 4:
        raise FormatError(f"corrupt .bdl file: a loop filter section of {len(section)} bytes")
    shape, shift, width, clip = section[:4]
    radius, cross, square = shape % 4, shape // 4 % 4, shape // 16
    checks = [
        (
            1 <= radius <= MAX_FILTER_RADIUS and cross <= MAX_FILTER_CROSS and square <= 1,
            f"bad loop filter shape {shape}",
        ),
        (not cross or 2 <= channels <= 3, f"cross-channel loop filter taps with {channels} channels"),
        (shift <= MAX_FILTER_SHIFT, f"loop filter shift {shift} (at most {MAX_FILTER_SHIFT})"),
        (2 <= width <= MAX_FILTER_WIDTH, f"loop filter coefficients of {width} bits"),
        (clip <= MAX_FILTER_CLIP, f"loop filter clipping {clip} (at most {MAX_FILTER_CLIP})"),
    ]
    for ok, message in checks:
        if not ok:
            raise FormatError(f"corrupt .bdl file: {message}")
    count = channels * filter_taps(radius, cross, channels, bool(square))
    if len(section) != filter_bytes(channels, count // channels, width):
        raise FormatError(
            f"corrupt .bdl file: a loop filter of {count} coefficients of {width} bits "
            f"in {len(section)} bytes"
        )
    value, total = int.from_bytes(section[4:], "big"), 8 * (len(section) - 4)
    coefficients = []
    for k in range(count):
        v = (value >> (total - (k + 1) * width)) & ((1 << width) - 1)
        coefficients.append(v - (1 << width) if v >> (width - 1) else v)
    return LoopFilter(
        radius=radius,
        cross=cross,
        clip=clip,
        shift=shift,
        coefficients=tuple(coefficients),
        square=bool(square),
    )
