"""``session.csv`` of a rehearsal (:data:`ctdrill.haptics.session.SESSION_COLUMNS`), written
through the project's one CSV writer (:mod:`ctdrill.app.csv_cells`)."""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from typing import IO

from ctdrill.app.csv_cells import CsvWriter
from ctdrill.haptics.session import SESSION_COLUMNS, Row, session_cells

#: ``session.csv``'s text column (the device state's name).
TEXT_COLUMNS = frozenset({"state"})


def session_csv_text(rows: Sequence[Row]) -> str:
    """``session.csv`` of ``rows`` as one text (the GUI's export), as :class:`SessionCsv`."""
    buf = io.StringIO()
    CsvWriter(buf, SESSION_COLUMNS, text_columns=TEXT_COLUMNS).writerows(session_cells(rows))
    return buf.getvalue()


class SessionCsv:
    """``session.csv`` writer, flushed after every block."""

    def __init__(self, path: Path) -> None:
        self._file: IO[str] = path.open("w", encoding="utf-8", newline="")
        self._writer = CsvWriter(self._file, SESSION_COLUMNS, text_columns=TEXT_COLUMNS)
        self._file.flush()

    def write(self, rows: Sequence[Row]) -> None:
        """Append rows and flush."""
        self._writer.writerows(session_cells(rows))
        self._file.flush()

    def close(self) -> None:
        """Close the file."""
        self._file.close()
