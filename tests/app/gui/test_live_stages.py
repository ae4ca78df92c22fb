"""A drag's path in two stages (issue 37): the curves and the stop first (``on_curves``), then
the implant's check and the problems; every number the same as the one-stage result's; in the
window the two stages run in runners of their own (the next curves never wait for checks)."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.implant_drag import dragged_plan
from ctdrill.app.gui.results import PathView, compute_path_view
from ctdrill.imaging import load_ct
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import Plan

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
    staged = compute_path_view(volume, moved, on_curves=first.append)
    whole = compute_path_view(volume, moved)
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
    np.testing.assert_array_equal(staged.implant.walls.wall_mm, whole.implant.walls.wall_mm)


def test_the_next_curves_do_not_wait_for_the_checks(
    qtbot: QtBot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A drag's checks run in a runner of their own: while the first position's checks are
    held, the next position's curves reach the document; the checks then follow for the
    latest position whose curves came, and the release takes its result."""
    from ctdrill.app.gui import controller as controller_module
    from ctdrill.app.gui.controller import Controller
    from ctdrill.app.gui.document import Document

    volume = load_ct(str(DEMO / "ct"))
    plan = load_plan(DEMO / "plan.json")
    doc = Document()
    doc.volume = volume
    doc.set_plan(plan)
    ctl = Controller(doc)
    # a worker running Python yields the interpreter to the UI thread within 0.5 ms
    assert sys.getswitchinterval() <= controller_module.UI_SWITCH_INTERVAL_S <= 0.001
    ctl.recompute()
    qtbot.waitUntil(lambda: doc.path is not None and doc.path.plan is plan, timeout=30_000)
    release = threading.Event()
    checked: list[Plan] = []
    original = controller_module.completed_view

    def held(volume_: object, first: PathView, **kw: object) -> PathView:
        checked.append(first.plan)
        assert release.wait(30.0)
        return original(volume_, first, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(controller_module, "completed_view", held)
    a, b, c = (
        dragged_plan(plan, "move", plan.target_lps, plan.target_lps + np.array([0, 0, dz]))
        for dz in (-0.5, -1.0, -1.5)
    )
    assert doc.live.drag_to(a)
    qtbot.waitUntil(lambda: checked == [a], timeout=30_000)  # a's checks held
    assert doc.live.curves is not None and doc.live.curves.plan is a
    assert doc.live.drag_to(b)
    qtbot.waitUntil(lambda: doc.live.curves.plan is b, timeout=30_000)  # type: ignore[union-attr]
    assert doc.live.drag_to(c)
    qtbot.waitUntil(lambda: doc.live.curves.plan is c, timeout=30_000)  # type: ignore[union-attr]
    assert checked == [a] and doc.live.path is None  # the checks still held
    release.set()
    qtbot.waitUntil(lambda: doc.live.path is not None and doc.live.path.plan is c, timeout=30_000)
    assert checked == [a, c]  # b's checks skipped: c's curves came before a's checks ended
    assert doc.live.path.curves is doc.live.curves.curves  # type: ignore[union-attr]
    assert doc.live.end_drag(c, edit="move implant")
    assert doc.path is not None and doc.path.plan is c
    ctl.cancel()
