"""Say so when numba compiles the kernels, instead of a silent first run.

The compiled kernels (``@njit(cache=True)`` throughout the package) are compiled on their first
call after installing (the first encode of a 512 x 512 map: under a minute on two cores), and
loaded from numba's cache in every later run. :func:`announce` listens to numba's compile events
(a cache hit raises none) and writes one line to stderr before the first compilation of the
process; with ``warm``, it also starts :mod:`bandelets.codec.warmup` in a process of its own,
which compiles the kernels the encoder reaches later on the other core meanwhile (the first
encode of a 512 x 512 map: 58 s of wall instead of 100 s of CPU on one core). The environment
variable ``BANDELETS_WARM_UP=0`` keeps that process from starting.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable

from numba.core import event

__all__ = ["COMPILING", "MESSAGE", "WARM_UP", "announce"]

#: What :func:`announce` writes.
MESSAGE = "bandelets: compiling kernels (first run only)..."


#: The environment variable that, set to ``0``, keeps :func:`announce` from starting the warm-up
#: process (the warm-up process itself runs with it).
WARM_UP = "BANDELETS_WARM_UP"
#: The environment variable through which the warm-up process learns the id of the process that
#: started it, compiling (the warm-up waits for that one's coefficient coder, not for nobody's).
COMPILING = "BANDELETS_WARM_UP_FOR"


class _Announcer(event.Listener):
    """At the first compilation it hears of: calls ``say(MESSAGE)`` (unless ``quiet``) and starts
    the warm-up process (if ``warm``)."""

    def __init__(self, say: Callable[[str], object]):
        self.say = say
        self.said = False
        self.quiet = False
        self.warm = False

    def on_start(self, _event) -> None:
        if not self.said:
            self.said = True
            if not self.quiet:
                self.say(MESSAGE)
            if self.warm:
                _start_warm_up()

    def on_end(self, _event) -> None:
        pass


def _to_stderr(message: str) -> None:
    try:  # whatever sys.stderr is by then
        print(message, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # closed: nobody to tell
        pass


_ANNOUNCER = _Announcer(_to_stderr)
_LISTENING = []


def _start_warm_up() -> None:
    """Start ``python -m bandelets.codec.warmup`` detached, its output discarded (nothing if
    :data:`WARM_UP` is ``0`` or the process cannot start: it only saves time)."""
    if os.environ.get(WARM_UP) == "0":
        return
    try:
        subprocess.Popen(
            [sys.executable, "-m", "bandelets.codec.warmup"],
            env={**os.environ, WARM_UP: "0", COMPILING: str(os.getpid())},
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
    except OSError:
        pass


def announce(quiet: bool = False, warm: bool = False) -> None:
    """Write :data:`MESSAGE` to stderr (unless ``quiet``) when numba first compiles a kernel in this
    process, and with ``warm`` start the warm-up process then (the first call's choices hold)."""
    _ANNOUNCER.quiet, _ANNOUNCER.warm = quiet, warm
    if not _LISTENING:
        event.register("numba:compile", _ANNOUNCER)
        _LISTENING.append(_ANNOUNCER)
