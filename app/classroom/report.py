"""``ctdrill class report``: the class's grades, confusion matrices and dashboard.

Writes into the output folder (replaced whole): ``grades.csv``
(:data:`~ctdrill.app.classroom.grades.GRADE_COLUMNS`), ``confusion.csv``
(:data:`~ctdrill.app.classroom.grades.CONFUSION_COLUMNS`), ``dashboard.png`` and
``dashboard.pdf``. Every CSV cell goes through the project's one CSV writer
(:func:`ctdrill.app.csv_cells.csv_table`): ids and names that start like a formula are
neutralised.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ctdrill.app.classroom.class_file import ClassFile, load_class
from ctdrill.app.classroom.dashboard import dashboard_files
from ctdrill.app.classroom.grades import (
    CONFUSION_COLUMNS,
    GRADE_COLUMNS,
    class_confusion,
    confusion_rows,
    grade_rows,
    learning_curves,
)
from ctdrill.app.csv_cells import csv_table
from ctdrill.app.records import atomic_output_dir, write_file

REPORT_FILES = frozenset({"grades.csv", "confusion.csv", "dashboard.png", "dashboard.pdf"})
_GRADE_TEXT = ("trainee", "exercise", "mode")
_CONFUSION_TEXT = ("exercise", "scope", "trainee", "truth")


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _table(rows: Sequence[Mapping[str, Any]], columns: Sequence[str], text: Sequence[str]) -> str:
    return csv_table(
        ({c: _cell(r.get(c)) for c in columns} for r in rows), columns, text_columns=text
    )


def class_tables(
    cls: ClassFile, sessions: Sequence[Mapping[str, Any]], answers: Sequence[Mapping[str, Any]]
) -> dict[str, bytes]:
    """The report's files by name (pure: the record's rows in, bytes out)."""
    grades = grade_rows(cls, sessions, answers)
    conf = confusion_rows(cls, answers)
    curves = learning_curves(cls, sessions, answers)
    accuracy: dict[str, float | None] = {}
    for t in cls.trainees:
        mine = [r for r in conf if r["scope"] == "trainee" and r["trainee"] == t]
        trials = sum(r["trials"] for r in mine)
        accuracy[t] = 100.0 * sum(r["correct"] for r in mine) / trials if trials else None
    png, pdf = dashboard_files(cls, curves, class_confusion(cls, answers), accuracy)
    return {
        "grades.csv": _table(grades, GRADE_COLUMNS, _GRADE_TEXT).encode("utf-8"),
        "confusion.csv": _table(conf, CONFUSION_COLUMNS, _CONFUSION_TEXT).encode("utf-8"),
        "dashboard.png": png,
        "dashboard.pdf": pdf,
    }


def write_class_report(db: Path, class_path: Path, out: Path) -> list[Path]:
    """Read the class file and the record, write the report (module docstring)."""
    import sqlite3

    from ctdrill.app.trainee.answers import answers
    from ctdrill.app.trainee.record import open_record, record_error

    cls = load_class(class_path)
    record = open_record(db, create=False)
    try:
        sessions = record.sessions()
        try:
            given = answers(record.conn)
        except sqlite3.Error as exc:
            raise record_error(db, exc) from exc
    finally:
        record.close()
    files = class_tables(cls, sessions, given)
    with atomic_output_dir(out, owned_names=REPORT_FILES) as stage:
        for name, data in files.items():
            write_file(stage / name, data)
    return [out / name for name in files]
