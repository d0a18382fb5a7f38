"""Never load numba kernels cached by an earlier install of the package.

Numba's cache (``@njit(cache=True)`` throughout the package) knows a kernel's own source file
only: a kernel that reads a constant or calls a kernel of another module
(``quantize.RECONSTRUCTION`` in ``bandeletize``, for instance) is loaded from the cache unchanged
after that other module changed. A ``pip install`` over an earlier version leaves the earlier
version's cache beside the new sources, and such stale kernels decode the new format wrongly.
So, at import, :func:`purge_stale_kernels` compares a digest of the package's sources with the
one it stamped in the cache, and deletes the cached kernels when they differ. Numba offers no
such check; hence this module. It does not import numba, so that the command line starts fast.

A source checkout (an editable install: ``src/bandelets`` beside the ``pyproject.toml``) is left
alone: there every edit would recompile all the kernels, and developers follow the rule written
beside such constants. (Not "inside a git repository": pyenv's Pythons, site-packages included,
live in one.)
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

__all__ = ["STAMP", "purge_stale_kernels"]

#: The file, in the package's ``__pycache__``, holding the digest of the sources the cache was
#: made from.
STAMP = "kernels.stamp"


def purge_stale_kernels(package: Path = Path(__file__).parents[1]) -> bool:
    """Delete numba's cached kernels (``__pycache__/*.nbi``, ``*.nbc``) under ``package`` if they
    were made from other sources than the package's current ones; returns whether it did.

    Nothing is done in a source checkout, and a folder that cannot be written is left as it is
    (numba then caches elsewhere, or not at all).
    """
    if (package.parent.parent / "pyproject.toml").exists():
        return False
    digest = hashlib.sha256()
    for source in sorted(package.rglob("*.py")):
        digest.update(source.relative_to(package).as_posix().encode() + b"\0" + source.read_bytes())
    stamp = package / "__pycache__" / STAMP
    try:
        if stamp.read_text() == digest.hexdigest():
            return False
    except (OSError, UnicodeDecodeError):
        pass
    try:
        for cached in [*package.rglob("__pycache__/*.nbi"), *package.rglob("__pycache__/*.nbc")]:
            cached.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        part = stamp.with_name(f"{STAMP}.{os.getpid()}")
        part.write_text(digest.hexdigest())
        os.replace(part, stamp)
    except OSError:
        return False
    return True
