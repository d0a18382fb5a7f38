"""Unsigned LEB128 integers, as the mesh records store their lengths (:mod:`bandelets.surfaces.chartcodec`,
:mod:`bandelets.surfaces.parts`) and the header its integers (:mod:`bandelets.format.header`, which reads
them with checks of its own).

Seven bits a byte, low first, the high bit set on every byte but the last. Written here: the standard
library has no LEB128, and the format is four lines.
"""

from __future__ import annotations

__all__ = ["read_varint", "varint"]

#: Bytes of the largest integer (below ``2**32``).
MOST_BYTES = 5


def varint(value: int) -> bytes:
    """The unsigned LEB128 bytes of ``0 <= value < 2**32``.

    Examples
    --------
    >>> varint(300).hex()
    'ac02'
    """
    if not 0 <= value < 2**32:
        raise ValueError(f"an integer from 0 to 2**32 - 1, not {value}")
    out = bytearray()
    while True:
        low, value = value & 127, value >> 7
        out.append(low | (128 if value else 0))
        if not value:
            return bytes(out)


def read_varint(
    data: bytes, offset: int, end: int | None = None, what: str = "corrupt file"
) -> tuple[int, int]:
    """The integer of ``data`` at ``offset`` (its bytes before ``end``, default the end of ``data``) and
    the offset after it; ``ValueError`` naming ``what`` where it is cut or longer than
    :data:`MOST_BYTES`.

    Examples
    --------
    >>> read_varint(bytes.fromhex("ac02ff"), 0)
    (300, 2)
    """
    end = len(data) if end is None else end
    value = shift = 0
    for k in range(MOST_BYTES):
        if offset + k >= end:
            break
        value |= (data[offset + k] & 127) << shift
        if not data[offset + k] & 128:
            return value, offset + k + 1
        shift += 7
    raise ValueError(f"{what} (bad length field)")
