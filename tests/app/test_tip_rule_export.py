"""The contract: every drill in ``summary.json``'s ``drills`` has the tip rule's tip."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from ctdrill.app.cli import main
from ctdrill.imaging.plan.drill_spec import tip_length_rule_mm
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"


def test_summary_drills_follow_the_tip_rule(tmp_path: Path) -> None:
    doc = json.loads((DEMO / "plan.json").read_text())
    doc.pop("drill")
    doc["drills"] = [{"diameter_mm": 2.0}, {"diameter_mm": 2.8}, {"diameter_mm": 3.5}]
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(doc))
    out = tmp_path / "out"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main(["export", "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    drills = summary["drills"]
    assert [d["tip_length_mm"] for d in drills] == [0.6, 0.8, 1.0]
    for d in drills:
        assert d["tip_length_mm"] == tip_length_rule_mm(d["diameter_mm"], d["point_angle_deg"])
        assert d["tip_override"] is False
    # each drill is drilled to the implant's apex plus its own tip
    apex = summary["implant"]["apex_depth_mm"]
    for d in drills:
        assert abs(d["planned_depth_mm"] - (apex + d["tip_length_mm"])) < 1e-6
