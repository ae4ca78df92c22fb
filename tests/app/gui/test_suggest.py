"""The *Suggest* action on the phantom: searched off the UI thread, the best feasible axes
drawn in 3D and listed, one adopted with a click (the plan takes its axis, the path follows)."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QPushButton
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.document import Document
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.suggesting import TOP_K, distinct_mm, top_rows
from ctdrill.app.search.candidates import SearchSpace
from ctdrill.app.search.defaults import DEFAULT_COUNT
from ctdrill.app.search.suggest import suggest
from ctdrill.imaging.phantom.io import PhantomCase
from ctdrill.imaging.plan.implants import load_implant_library
from ctdrill.model import load_calibration
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, SEARCH_TIMEOUT_MS, open_case
from tests.app.gui.phantom import phantom_volume

pytestmark = pytest.mark.gui


def _shorter_implant(case: PhantomCase, folder: Path) -> PhantomCase:
    """The case with an 8 mm implant whose apex lies 10.5 mm deep: the planned axis still
    breaks the canal's margin (the drill's tip goes 0.6 mm beyond the apex), tilted axes
    beside it keep every margin and bone wall (the case's own 11.5 mm implant leaves none:
    every axis that keeps the canal's margin leaves the ridge)."""
    doc = json.loads(case.plan_path.read_text(encoding="utf-8"))
    spec = next(s for s in load_implant_library() if s.name == "tapered 4.1 x 8")
    doc["target_mm"] = [doc["entry_mm"][0], doc["entry_mm"][1], doc["entry_mm"][2] - 10.5]
    doc["implant"] = spec.to_json()
    path = folder / "short.plan.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return replace(case, plan_path=path)


def test_suggest_draws_the_top_axes_and_a_click_adopts_one(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, _shorter_implant(phantom_case, tmp_path))
    assert window.view is not None
    planned_stop = window.view.curves.stop_reason
    planned = window.plan
    panel = window.suggest_panel
    assert panel.count.value() == DEFAULT_COUNT  # the command's default, 2000
    assert window.suggest_axes()
    assert window.doc.suggest_status == "running" and not panel.button.isEnabled()
    qtbot.waitUntil(lambda: window.doc.suggestion is not None, timeout=SEARCH_TIMEOUT_MS)
    s = window.doc.suggestion
    assert s is not None and s.plan is planned and s.candidates.size == DEFAULT_COUNT
    rows = top_rows(s)
    assert len(rows) == TOP_K and rows[0].rank == 1 and rows[0].index == s.best_index
    # Distinct axes: every feasible candidate ranked above the last one shown is shown or
    # within a drill diameter (entry and target) of a shown one.
    assert distinct_mm(s) == planned.drill.diameter_mm == 2.0
    c = s.candidates
    shown_ix = [r.index for r in rows]

    def near(i: int, j: int) -> bool:
        return bool(
            np.linalg.norm(c.entries_lps[i] - c.entries_lps[j]) < distinct_mm(s)
            and np.linalg.norm(c.targets_lps[i] - c.targets_lps[j]) < distinct_mm(s)
        )

    assert not any(near(i, j) for i in shown_ix for j in shown_ix if i != j)
    for i in s.order[: rows[-1].rank]:
        assert s.feasible[i] and (int(i) in shown_ix or any(near(int(i), j) for j in shown_ix))
    assert [r.rank for r in rows] == sorted(r.rank for r in rows)
    # The best feasible ones, then the planned axis (not feasible here) with its rank.
    assert panel.table.rowCount() == len(rows) + 1
    shown = [panel.table.item(r, 1).text() for r in range(len(rows) + 1)]  # type: ignore[union-attr]
    assert shown == [str(r.rank) for r in rows] + ["plan"]
    back = panel.table.cellWidget(len(rows), 0)
    assert isinstance(back, QPushButton) and back.text() == "current" and not back.isEnabled()
    # The 3D view draws one line per shown candidate (after its queued build).
    qtbot.waitUntil(
        lambda: {f"candidate:{r.rank}" for r in rows} <= set(window.view3d.actors),
        timeout=LOAD_TIMEOUT_MS,
    )
    # Click the second candidate's Adopt button: the plan takes its axis, nothing else.
    slot = min(1, len(rows) - 1)  # the table's row: rows in order, ranks may skip
    pick = rows[slot]
    button = panel.table.cellWidget(slot, 0)
    assert isinstance(button, QPushButton)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseClick(button, Qt.MouseButton.LeftButton)
    plan = window.plan
    assert plan is not None and plan is not planned
    assert np.array_equal(plan.entry_lps, s.candidates.entries_lps[pick.index])
    assert np.array_equal(plan.target_lps, s.candidates.targets_lps[pick.index])
    assert plan.drill == planned.drill and plan.landmarks == planned.landmarks
    assert window.doc.adopted == pick.index and window.doc.suggestion is s
    # Feasible: the recomputed path reaches the planned depth.
    assert window.view is not None and window.view.curves.stop_reason == "planned_depth"
    adopted = panel.table.cellWidget(slot, 0)
    assert isinstance(adopted, QPushButton) and adopted.text() == "adopted"
    qtbot.waitUntil(
        lambda: f"candidate:{pick.rank}" in window.view3d.actors, timeout=LOAD_TIMEOUT_MS
    )
    qtbot.wait(300)  # the plots redraw on the next idle pass
    shot = Path(os.environ.get("CTDRILL_SUGGEST_SCREENSHOT", tmp_path / "suggest.png"))
    window.save_screenshot(shot)
    assert shot.stat().st_size > 10_000
    # The plan row's button goes back to the planned axis.
    back = panel.table.cellWidget(len(rows), 0)
    assert isinstance(back, QPushButton) and back.text() == "Back" and back.isEnabled()
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseClick(back, Qt.MouseButton.LeftButton)
    assert window.plan is not None
    assert np.array_equal(window.plan.entry_lps, planned.entry_lps)
    assert np.array_equal(window.plan.target_lps, planned.target_lps)
    assert window.view is not None and window.view.curves.stop_reason == planned_stop
    plan = window.plan
    # Any other edit drops the suggestion (its feasibility was for the old plan).
    moved = plan.target_lps + np.array([0.0, 0.0, 1.0])
    window.slice_canvases["coronal"].point_moved.emit("target", moved)
    assert window.doc.suggestion is None and panel.table.rowCount() == 0


def test_the_document_keeps_a_suggestion_only_for_its_plan(qtbot: QtBot) -> None:
    doc = Document()
    vol = phantom_volume()
    from tests.app.gui.test_document import plan

    first = plan(-0.0)
    assert not doc.request_suggestion(SearchSpace(count=3))  # no series, no plan
    doc.volume = vol
    doc.set_plan(first)
    cal = load_calibration("bone-illustrative")
    s = suggest(vol, first, cal, SearchSpace(count=3))
    doc.set_suggestion(first, s)  # not asked for: dropped
    assert doc.suggestion is None
    with qtbot.waitSignal(doc.suggestion_requested, timeout=LOAD_TIMEOUT_MS):
        assert doc.request_suggestion(SearchSpace(count=3))
    doc.set_suggestion(first, s)
    assert doc.suggestion is s and doc.suggest_status == ""
    assert doc.adopt_candidate(2) and doc.adopted == 2 and doc.suggestion is s
    assert np.array_equal(doc.plan.entry_lps, s.candidates.entries_lps[2])  # type: ignore[union-attr]
    doc.set_plan(first)
    assert doc.suggestion is None and doc.adopted is None
