"""Third-party messages on the standard error held back while a read may fail (issue 40).

libpng prints warnings (``PNG warning: Image width is zero in IHDR``) on file descriptor 2, from C,
before imagecodecs raises the error the command line turns into its one line: the user saw three
lines for one problem. :func:`held_stderr` points descriptor 2 at a temporary file for the length
of the read and, when the read succeeds, prints what was held (a warning about a file that was
read is news); when it fails, the error says it all and the held text is dropped.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator

__all__ = ["held_stderr"]


@contextlib.contextmanager
def held_stderr() -> Iterator[None]:
    """Hold what is written on file descriptor 2 inside the block; write it out if the block
    succeeds, drop it if the block raises. Without a descriptor 2 to redirect, does nothing."""
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:
        yield
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        succeeded = False
        try:
            yield
            succeeded = True
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            if succeeded:
                sink.seek(0)
                held = sink.read()
                if held:
                    with contextlib.suppress(OSError):
                        os.write(2, held)
