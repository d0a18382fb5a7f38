"""Say so when numba compiles the kernels, instead of a silent first run.

The compiled kernels (``@njit(cache=True)`` throughout the package) are compiled on their first
call after installing, about half a minute in all on two cores, and loaded from numba's cache
in every later run. :func:`announce` listens to numba's compile events (a cache hit raises
none) and writes one line to stderr before the first compilation of the process.
"""

from __future__ import annotations

import sys
from collections.abc import Callable

from numba.core import event

__all__ = ["MESSAGE", "announce"]

#: What :func:`announce` writes.
MESSAGE = "bandelets: compiling kernels (first run only)..."


class _Announcer(event.Listener):
    """Calls ``say(MESSAGE)`` at the first compilation it hears of."""

    def __init__(self, say: Callable[[str], object]):
        self.say = say
        self.said = False

    def on_start(self, _event) -> None:
        if not self.said:
            self.said = True
            self.say(MESSAGE)

    def on_end(self, _event) -> None:
        pass


def _to_stderr(message: str) -> None:
    try:  # whatever sys.stderr is by then
        print(message, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # closed: nobody to tell
        pass


_ANNOUNCER = _Announcer(_to_stderr)
_LISTENING = []


def announce() -> None:
    """Write :data:`MESSAGE` to stderr when numba first compiles a kernel in this process
    (calling again changes nothing)."""
    if not _LISTENING:
        event.register("numba:compile", _ANNOUNCER)
        _LISTENING.append(_ANNOUNCER)
