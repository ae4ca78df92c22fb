"""A progress bar for commands that run several jobs (``ctdrill export``, ``ctdrill report``).

It goes to stdout: stderr is kept for ``error:`` and warning lines, so a refusal is the one
line there (a bar drawn before it would be a second).
"""

from __future__ import annotations

import sys
from typing import TextIO


class TextProgress:
    """A progress bar on ``stream`` for more than one job: redrawn in place on a terminal,
    one line per step otherwise. :meth:`close` ends a bar left unfinished (on error)."""

    def __init__(
        self, stream: TextIO = sys.stdout, *, width: int = 30, label: str = "export"
    ) -> None:
        self.stream = stream
        self.width = width
        self.label = label
        self._open = False

    def __call__(self, done: int, total: int, label: str) -> None:
        if total <= 1:
            return
        filled = int(self.width * done / total)
        bar = f"{self.label} [{'#' * filled}{'.' * (self.width - filled)}] {done}/{total} {label}"
        if self.stream.isatty():
            self.stream.write("\r" + bar + ("\n" if done >= total else ""))
            self._open = done < total
        else:
            self.stream.write(bar + "\n")
        self.stream.flush()

    def close(self) -> None:
        """End the line of an unfinished bar so that what follows starts a line."""
        if self._open:
            self.stream.write("\n")
            self._open = False
