"""The header's LEB128 integers (format version 17), read and written by the tests' own code, not
the package's: a second reading of the format."""

from __future__ import annotations


def leb128(value: int) -> bytes:
    """The unsigned LEB128 bytes of ``value``."""
    out = bytearray()
    while value >= 128:
        out.append(value & 127 | 128)
        value >>= 7
    return bytes(out + bytes([value]))


def read_integers(data: bytes, start: int, count: int) -> tuple[list[int], int]:
    """``count`` LEB128 integers of ``data`` from ``start``, and the offset after them."""
    values = []
    for _ in range(count):
        value = shift = 0
        while data[start] >= 128:
            value, shift, start = value | (data[start] & 127) << shift, shift + 7, start + 1
        values.append(value | data[start] << shift)
        start += 1
    return values, start


def integer_count(data: bytes) -> int:
    """The LEB128 integers of a .bdl header (format version 19): height, width and three segment
    lengths per group of levels but group 0's one (one group for a lossless file, transform code 2)."""
    levels, transform = data[7] % 8, data[6] % 4
    return 3 * (1 if transform == 2 else levels + 1)
