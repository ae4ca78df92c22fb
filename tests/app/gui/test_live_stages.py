"""A drag's path in two stages (issue 37): the curves and the stop first (``on_curves``), then
the implant's check and the problems; every number the same as the one-stage result's."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ctdrill.app.gui.implant_drag import dragged_plan
from ctdrill.app.gui.results import PathView, compute_path_view
from ctdrill.imaging import load_ct
from ctdrill.imaging.plan.load import load_plan

ROOT = Path(__file__).resolve().parents[3]
DEMO = ROOT / "assets" / "demo"


def test_the_curves_come_first_and_equal_the_whole_results() -> None:
    volume = load_ct(str(DEMO / "ct"))
    plan = load_plan(DEMO / "plan.json")
    assert plan.implant is not None and len(plan.drills) == 1
    moved = dragged_plan(
        plan, "move", plan.target_lps, plan.target_lps + np.array([0.4, 0.0, -1.5])
    )
    first: list[PathView] = []
    staged = compute_path_view(volume, moved, live=True, on_curves=first.append)
    whole = compute_path_view(volume, moved, live=True)
    assert len(first) == 1
    early = first[0]
    assert early.plan is moved and early.implant is None and early.problems == ()
    assert early.result.implant is None and early.result.warnings == ()
    assert staged.curves is early.curves  # the curves shown first are the final ones
    for name in ("depth_mm", "hu", "force_n", "clearance_mm"):
        np.testing.assert_array_equal(getattr(early.curves, name), getattr(whole.curves, name))
    assert early.curves.stop_depth_mm == whole.curves.stop_depth_mm
    assert early.curves.stop_reason == whole.curves.stop_reason
    assert staged.result.implant is not None
    assert [w.code for w in staged.problems] == [w.code for w in whole.problems]
    assert [w.code for w in staged.result.warnings] == [w.code for w in whole.result.warnings]
    assert staged.implant is not None and whole.implant is not None
    assert staged.implant.walls is not None and whole.implant.walls is not None
    assert staged.implant.walls.min_mm == whole.implant.walls.min_mm
    assert not staged.implant.coarse and not whole.implant.coarse  # the full grid
