"""``ctdrill export`` gives the numbers it gave before a refactoring: the demo and two shipped
series against ``tests/data/export_golden.json`` (the previous release's outputs).

The record holds each case's whole ``summary.json`` and every 5th row of ``profile.csv``.
Numbers are compared to the precision they are written with: ``profile.csv`` to one unit of
its last decimal, ``summary.json``'s unrounded floats (bone walls) to 1e-7 relative (far
below a voxel, far above a BLAS kernel's rounding); strings and lists of codes exactly; a key
the record lacks (a field added since) is not compared. A change meant to move the numbers
rewrites the record, reviewed in its diff::

    .venv/bin/python -m tests.app.test_export_golden --write
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import sys
import tempfile
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.cli import main
from tests.conftest import ASSETS, ROOT, SHARED_DATA

RECORD = ROOT / "tests" / "data" / "export_golden.json"
#: name -> the export's input options (paths relative to the repository / the shared data)
CASES: dict[str, list[str]] = {
    "demo": ["--dicom", str(ASSETS / "demo" / "ct"), "--plan", str(ASSETS / "demo" / "plan.json")],
    "philips_head_arch": [
        "--dicom",
        str(SHARED_DATA / "dcmqa_ct_Philips_phantom_notilt_5mm"),
        "--plan",
        str(ROOT / "tests" / "data" / "philips_head_arch.plan.json"),
    ],
    "headsq_quarter": [
        "--ct",
        str(SHARED_DATA / "vtk_headsq_quarter" / "headsq_quarter.nii.gz"),
        "--plan",
        str(ROOT / "tests" / "data" / "headsq_quarter.plan.json"),
    ],
}
#: Keys that name where the files were, not what was computed.
UNCOMPARED = frozenset({"plan_file"})
PROFILE_EVERY = 5


def export_outputs(case: str, out: Path) -> dict[str, Any]:
    """Run the export of ``case`` into ``out``: its summary and every 5th profile row."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(["export", *CASES[case], "--out", str(out)])
    assert code == 0, stderr.getvalue()
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    with (out / "profile.csv").open(newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return {
        "summary": {k: v for k, v in summary.items() if k not in UNCOMPARED},
        "profile": [rows[0], *rows[1::PROFILE_EVERY]],
    }


def _cell_close(got: str, want: str) -> bool:
    """Two CSV cells: equal text, or numbers within one unit of the last written decimal."""
    if got == want:
        return True
    try:
        g, w = float(got), float(want)
    except ValueError:
        return False
    decimals = len(want.partition(".")[2])
    return abs(g - w) <= 1.5 * 10.0**-decimals


def _differences(got: Any, want: Any, where: str) -> list[str]:
    if isinstance(want, dict) and isinstance(got, dict):
        out = [f"{where}.{k}: missing" for k in want if k not in got]  # a new key is no change
        for k in want.keys() & got.keys():
            out += _differences(got[k], want[k], f"{where}.{k}")
        return out
    if isinstance(want, list) and isinstance(got, list):
        if len(want) != len(got):
            return [f"{where}: {len(got)} items, recorded {len(want)}"]
        out = []
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            out += _differences(g, w, f"{where}[{i}]")
        return out
    if isinstance(want, float) or isinstance(got, float):
        numbers = isinstance(got, int | float) and isinstance(want, int | float)
        if numbers and math.isclose(got, want, rel_tol=1e-7, abs_tol=1e-6):
            return []
        return [f"{where}: {got!r}, recorded {want!r}"]
    return [] if got == want else [f"{where}: {got!r}, recorded {want!r}"]


def _profile_differences(got: list[list[str]], want: list[list[str]], case: str) -> list[str]:
    if len(got) != len(want) or got[0] != want[0]:
        return [f"{case} profile.csv: {len(got)} rows / {got[0]}, recorded {len(want)} / {want[0]}"]
    return [
        f"{case} profile.csv row {i * PROFILE_EVERY} {want[0][j]}: {g}, recorded {w}"
        for i, (grow, wrow) in enumerate(zip(got[1:], want[1:], strict=True))
        for j, (g, w) in enumerate(zip(grow, wrow, strict=True))
        if not _cell_close(g, w)
    ]


@pytest.mark.parametrize("case", sorted(CASES))
def test_export_gives_the_recorded_numbers(case: str, tmp_path: Path) -> None:
    recorded = json.loads(RECORD.read_text(encoding="utf-8"))[case]
    got = export_outputs(case, tmp_path / case)
    problems = _differences(got["summary"], recorded["summary"], f"{case} summary")
    problems += _profile_differences(got["profile"], recorded["profile"], case)
    assert not problems, "\n".join(problems[:20])


def write_record() -> None:
    """Rewrite :data:`RECORD` from the current code (a change meant to move the numbers)."""
    with tempfile.TemporaryDirectory() as tmp:
        record = {case: export_outputs(case, Path(tmp) / case) for case in sorted(CASES)}
    RECORD.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {RECORD}")


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        raise SystemExit("usage: python -m tests.app.test_export_golden --write")
    write_record()
