"""Temporary files of :func:`bandelets.files.write_atomic`, named so that they are recognisably
ours, and the removal of those an interrupted run left behind (issue 40).

An output is written to a temporary file beside it and renamed over it, so that a reader never
sees half a file; a process killed between the two (``kill -9``, a power cut) leaves the
temporary file. Its name says what it is, ``.OUT.XXXXXXXX.bandelets-tmp`` (``OUT`` the output's
name, ``XXXXXXXX`` the random part of :func:`tempfile.mkstemp`), and the first write of a process
in a folder removes the files of exactly that pattern that are older than :data:`STALE_SECONDS`
(no run writes one for that long: it is written whole, then renamed) and are regular files of
the user who runs it. Nothing else in the folder is touched.
"""

from __future__ import annotations

import os
import re
import tempfile
import time
from pathlib import Path

__all__ = ["SUFFIX", "STALE_SECONDS", "is_ours", "make", "remove_stale"]

#: Suffix of our temporary files.
SUFFIX = ".bandelets-tmp"
#: Age from which a temporary file of ours is taken to be left by an interrupted run.
STALE_SECONDS = 3600.0
# ".OUT." + mkstemp's 8 random characters (lower-case letters, digits, "_") + SUFFIX.
_PATTERN = re.compile(r"\..+\.[a-z0-9_]{8}" + re.escape(SUFFIX))
# Folders already cleaned by this process: a batch writing thousands of files into one folder
# scans it once.
_CLEANED: set[str] = set()


def is_ours(name: str) -> bool:
    """Whether the file name ``name`` is one :func:`make` gives."""
    return _PATTERN.fullmatch(name) is not None


def make(path: Path) -> tuple[int, str]:
    """A new temporary file for the output ``path``, in its folder: ``(descriptor, path)``
    (:func:`tempfile.mkstemp`); the folder's stale ones are removed first (:func:`remove_stale`)."""
    folder = path.parent or Path(".")
    remove_stale(folder)
    return tempfile.mkstemp(prefix=f".{path.name}.", suffix=SUFFIX, dir=folder)


def remove_stale(folder: Path, now: float | None = None, force: bool = False) -> list[str]:
    """Remove from ``folder`` our temporary files (:func:`is_ours`) older than
    :data:`STALE_SECONDS`, regular files of this user only; once per folder and process unless
    ``force``. Returns the names removed; errors (a file gone meanwhile, no permission) are ignored."""
    key = os.path.abspath(folder)
    if key in _CLEANED and not force:
        return []
    _CLEANED.add(key)
    now = time.time() if now is None else now
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        if not is_ours(entry.name):
            continue
        try:
            info = entry.stat(follow_symlinks=False)
            if not entry.is_file(follow_symlinks=False) or now - info.st_mtime < STALE_SECONDS:
                continue
            if hasattr(os, "getuid") and info.st_uid != os.getuid():
                continue
            os.unlink(entry.path)
            removed.append(entry.name)
        except OSError:
            continue
    return removed
