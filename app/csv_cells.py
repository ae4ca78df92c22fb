"""Cells of every CSV table ctdrill writes, safe to open in a spreadsheet.

A spreadsheet runs a cell that starts with ``=``, ``+``, ``-`` or ``@`` as a formula
(``=HYPERLINK(...)``, ``+cmd|' /C calc'!A0``, ``@SUM(...)``), and a leading tab or carriage
return can hide one. Row ids, trajectory and landmark names, plan paths, calibration names
and error lines come from users' files, so every text cell that starts with one of
:data:`FORMULA_STARTS` is written with a single quote in front, as OWASP's CSV-injection
guidance says (the quote shows; nothing runs). Numbers stay numbers: in a numeric column a
decimal number (``-12.5``, ``1e-05``) is written as it is; anything else there is text and
neutralised the same way. Quotes, commas and line breaks inside cells are quoted by
:mod:`csv` (a carriage return is written as a line feed, which it quotes).

This module is the one CSV writer of the project: every CSV file ctdrill writes
(``force.csv``, ``profile.csv``, ``session.csv`` of a rehearsal and of a teleoperation,
``status.csv`` and ``trajectories.csv`` of an export and of a batch, ``candidates.csv``,
``alternatives.csv``, ``grades.csv``, ``confusion.csv``, ``assess --out``'s
``learning_curve.csv`` and ``percentiles.csv``) is written by :func:`csv_table`,
:func:`csv_text`, :class:`CsvWriter` or :func:`csv_row`, every cell through
:func:`text_cell` / :func:`number_cell`; ``tests/test_csv_writer.py`` fails when another
module writes CSV otherwise.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Collection, Iterable, Mapping, Sequence
from typing import IO

#: First characters that make a spreadsheet read a cell as a formula (OWASP).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
#: What a neutralised cell starts with.
NEUTRAL_PREFIX = "'"
#: A decimal number as ctdrill writes one (no spaces, no thousands separators).
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def text_cell(text: str) -> str:
    """``text`` as a CSV cell that no spreadsheet runs: quoted with ``'`` when it starts
    with one of :data:`FORMULA_STARTS`; a carriage return inside it becomes a line feed (the
    :mod:`csv` writer quotes a cell holding a line feed, not one holding a lone carriage
    return, which readers take for the end of the row: a forged row)."""
    risky = text.startswith(FORMULA_STARTS)
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    return NEUTRAL_PREFIX + text if risky else text


def number_cell(text: str) -> str:
    """A numeric column's cell: a decimal number as it is, anything else as :func:`text_cell`."""
    return text if _NUMBER.fullmatch(text) else text_cell(text)


def csv_table(
    rows: Iterable[Mapping[str, str]],
    columns: Sequence[str],
    *,
    text_columns: Collection[str],
) -> str:
    """CSV text of ``rows`` (dicts keyed by ``columns``) with a header line.

    Cells of ``text_columns`` go through :func:`text_cell`, every other cell through
    :func:`number_cell` (so a column not declared text is still never a formula).
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for row in rows:
        extra = set(row) - set(columns)
        if extra:
            raise ValueError(f"cells outside the table's columns: {sorted(extra)}")
        w.writerow(
            [
                text_cell(row.get(c, "")) if c in text_columns else number_cell(row.get(c, ""))
                for c in columns
            ]
        )
    return buf.getvalue()


def _cells(row: Sequence[object], text_at: Collection[int]) -> list[str]:
    out = []
    for i, value in enumerate(row):
        cell = "" if value is None else str(value)
        out.append(text_cell(cell) if i in text_at else number_cell(cell))
    return out


class CsvWriter:
    """Rows of a CSV table written to ``stream`` (a header first), every cell neutralised:
    a column named in ``text_columns`` through :func:`text_cell`, any other through
    :func:`number_cell`. Cells may be strings (formatted by the caller), numbers or None
    (empty)."""

    def __init__(
        self, stream: IO[str], header: Sequence[str], *, text_columns: Collection[str] = ()
    ) -> None:
        self._writer = csv.writer(stream, lineterminator="\n")
        self._text_at = frozenset(i for i, c in enumerate(header) if c in text_columns)
        self._writer.writerow([text_cell(c) for c in header])

    def writerow(self, row: Sequence[object]) -> None:
        """One row."""
        self._writer.writerow(_cells(row, self._text_at))

    def writerows(self, rows: Iterable[Sequence[object]]) -> None:
        """Several rows."""
        text_at = self._text_at
        self._writer.writerows(_cells(row, text_at) for row in rows)


def csv_text(
    header: Sequence[str],
    rows: Iterable[Sequence[object]],
    *,
    text_columns: Collection[str] = (),
) -> str:
    """CSV text of ``rows`` (sequences in ``header``'s order) with a header line, written by
    :class:`CsvWriter`."""
    buf = io.StringIO()
    CsvWriter(buf, header, text_columns=text_columns).writerows(rows)
    return buf.getvalue()


def csv_row(cells: Sequence[object], *, text: bool = False) -> str:
    """One CSV line (with its line feed) of ``cells``, each through :func:`text_cell`
    (``text``) or :func:`number_cell`: the header and the constant cells around a table
    formatted elsewhere (:func:`ctdrill.app.fixedtext.fixed_csv`)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(_cells(cells, range(len(cells)) if text else ()))
    return buf.getvalue()
