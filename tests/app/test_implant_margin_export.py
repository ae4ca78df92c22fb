"""The case issue 25 was found with, through the command line and the Python API: on the demo
CT, entry (36.1, 10, -30.5), target (36.1, 10, -42.5), implant ``parallel 4.1 x 11.5``,
``bone-literature``, the default drill. The drill's path keeps more than 1.9 mm from the canal,
but the implant body lies 0.91 mm from it: the outputs must say so.

Cost: one export of the 80-slice demo and one implant outcome (about 3 s on an idle core).
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from ctdrill import api
from ctdrill.app.cli import main
from ctdrill.imaging.plan.implants import load_implant_library
from ctdrill.resources import asset

DEMO = asset("demo")
#: The implant body's clearance to the canal, mm, as the issue measured it.
CLEARANCE_MM = 0.91


def _plan(tmp: Path) -> Path:
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    lib = {s.name: s for s in load_implant_library()}
    doc.update(
        entry_mm=[36.1, 10.0, -30.5],
        target_mm=[36.1, 10.0, -42.5],
        implant=lib["parallel 4.1 x 11.5"].to_json(),
        calibration="bone-literature",
        drill={"diameter_mm": 2.0, "tip_length_mm": 0.6},
    )
    doc.pop("series_uid_sha256", None)
    path = tmp / "issue25.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def test_the_issue_case_warns_through_the_cli_and_the_api(tmp_path: Path) -> None:
    plan = _plan(tmp_path)
    out = tmp_path / "out"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = main(["export", "--ct", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)])
    assert code == 0
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    codes = [w["code"] for w in s["warnings"]]
    assert "implant_violates_margin" in codes
    assert s["implant_clearance_mm"] == pytest.approx(CLEARANCE_MM, abs=0.005)
    assert s["implant_binding_landmark"] == {"name": "left mandibular canal", "margin_mm": 2.0}
    # the drill's own margin is checked at its drilled depth: the apex 12 mm plus its tip
    assert s["planned_depth_mm"] == pytest.approx(12.6) and s["overdrill_mm"] == 0.6
    assert s["target_lps"] == [36.1, 10.0, -42.5]
    # plan_violates_margin covers the implant body
    assert any(
        w["code"] == "plan_violates_margin" and "implant body" in w["message"]
        for w in s["warnings"]
    )
    walls = s["bone_walls"]
    assert set(walls) >= {"min_mm", "depth_mm", "direction_lps", "buccal_mm", "lingual_mm"}
    assert walls["outside_ct"] == "outside the CT counts as unknown, never as bone"
    # 0.4 mm voxels: clearances known to +-0.2 mm, printed with one decimal
    assert s["clearance_accuracy_mm"] == 0.2
    text = stdout.getvalue()
    assert "implant 'parallel 4.1 x 11.5' clearance 0.9 mm to 'left mandibular canal'" in text
    assert "warning [implant_violates_margin]" in text
    # the Python API gives the same number
    outcome = api.implant_outcome(api.load_series(DEMO / "ct"), api.load_plan(plan))
    assert outcome is not None and "implant_violates_margin" in outcome.codes
    assert outcome.clearance_mm == pytest.approx(s["implant_clearance_mm"], abs=1e-4)
