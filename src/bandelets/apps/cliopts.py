"""Numeric command-line options parsed with their bounds (issue 40).

``argparse``'s ``type=float`` takes ``inf``, ``nan`` and ``1e400`` (infinite), and ``type=int``
any negative number: each then failed later, some with a traceback (``int(inf)`` is an
``OverflowError``, not a ``ValueError``). The functions here are ``type=`` functions that refuse
such a value when the command line is parsed, with :class:`argparse.ArgumentTypeError`, which the
parser turns into the CLI's one-line usage error (exit status 2).
"""

from __future__ import annotations

import argparse
import math

__all__ = [
    "MAX_MEMORY_BYTES",
    "effort_level",
    "memory_size",
    "natural_int",
    "positive_float",
    "positive_int",
    "rate_list",
]

#: Largest ``--max-memory`` accepted: 2**50 bytes (1 PiB), far above any machine, and an ``int``
#: every computation with it keeps exact.
MAX_MEMORY_BYTES = 2**50


def positive_float(text: str) -> float:
    """A finite number above 0 (refuses ``inf``, ``nan``, ``1e400``, zero and negatives)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number (finite), got {text!r}")
    return value


def _integer(text: str) -> int:
    try:
        return int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def positive_int(text: str) -> int:
    """A whole number above 0."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}")
    return value


def effort_level(text: str) -> int:
    """An encoder's effort, a whole number from 1 to 9 (``--effort``)."""
    value = _integer(text)
    if not 1 <= value <= 9:
        raise argparse.ArgumentTypeError(f"expected a whole number from 1 to 9, got {text!r}")
    return value


def natural_int(text: str) -> int:
    """A whole number from 0 (``--tile 0``: the default choice)."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number from 0, got {text!r}")
    return value


def memory_size(text: str) -> int:
    """Bytes of a ``--max-memory`` value: MiB, or a number with a K, M or G suffix; finite,
    positive and at most :data:`MAX_MEMORY_BYTES`."""
    scale = {"K": 2**10, "M": 2**20, "G": 2**30}.get(text[-1:].upper())
    try:
        value = float(text[:-1] if scale else text) * (scale or 2**20)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a size such as 512M or 4G, got {text!r}") from None
    if not value > 0:  # nan too
        raise argparse.ArgumentTypeError(f"the memory limit must be positive, got {text!r}")
    if not value <= MAX_MEMORY_BYTES:  # inf, 1e400
        raise argparse.ArgumentTypeError(
            f"the memory limit must be at most 1048576G (2**50 bytes), got {text!r}"
        )
    return max(1, int(value))


def rate_list(text: str, option: str) -> list[float]:
    """The finite positive numbers of a comma-separated list (``--rates``), or a ``ValueError``
    naming ``option``."""
    try:
        return [positive_float(r) for r in text.split(",") if r.strip()]
    except argparse.ArgumentTypeError:
        raise ValueError(
            f"{option} must be a comma-separated list of finite positive numbers, got {text!r}"
        ) from None
