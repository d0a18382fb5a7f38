"""One progress line for a whole encode, naming the stage it is in (tqdm).

The encoder's stages take an unknown number of steps (rate control stops when the target is
met, the restoration search when it stops improving), so the line counts the steps of the
current stage, names it, and says what the last step found.
"""

from __future__ import annotations

from tqdm import tqdm

__all__ = ["Progress"]


class Progress:
    """``stage(name)`` enters a stage, ``step(note)`` counts one step of it; a no-op when disabled.

    A stage entered again (rate control after each restoration search) goes on counting where it
    was, unless ``restart``. Use as a context manager: the line is erased at the end (``leave=False``).
    """

    def __init__(self, enabled: bool = False):
        self._bar = tqdm(
            disable=not enabled, leave=False, unit="step", bar_format="{desc}: {n_fmt}{postfix} [{elapsed}]"
        )
        self._counts: dict[str, int] = {}
        self._stage = ""

    def stage(self, name: str, restart: bool = False) -> None:
        self._stage = name
        if restart:
            self._counts[name] = 0
        self._bar.n = self._counts.get(name, 0)
        self._bar.set_description_str(name, refresh=False)
        self._bar.set_postfix_str("", refresh=True)

    def step(self, note: str = "") -> None:
        self._counts[self._stage] = self._counts.get(self._stage, 0) + 1
        self._bar.set_postfix_str(note, refresh=False)
        self._bar.update()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self._bar.close()
