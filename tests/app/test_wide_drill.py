"""A drill wider than the scan around its axis (issue 36): the export and the rehearsal refuse
it with one error line (exit 2), nothing written, instead of drilling on a lip read as air."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ctdrill.app.cli import main

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


@pytest.mark.parametrize(("command", "diameter_mm"), [("export", 36.0), ("rehearse", 45.0)])
def test_a_drill_wider_than_the_scan_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, diameter_mm: float
) -> None:
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc.pop("implant", None)
    doc["drill"] = {"diameter_mm": diameter_mm, "blades": 2, "rpm": 900}
    plan = tmp_path / "wide.json"
    plan.write_text(json.dumps(doc), encoding="utf-8")
    out = tmp_path / "out"
    argv = [command, "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)]
    if command == "rehearse":
        argv += ["--operator", "push:20", "--duration-s", "0.5"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "Traceback" not in err
    assert f"the drill ({diameter_mm:g} mm) is wider than the scan around its axis" in err
    assert not out.exists()
