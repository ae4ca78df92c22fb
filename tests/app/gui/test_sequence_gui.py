"""A drill sequence in the window: the panel lists the drills, the path is the final drill's
around the earlier holes, the auto-stop text says which drill, edits change the final drill."""

from __future__ import annotations

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging.phantom.io import PhantomCase
from ctdrill.imaging.plan.types import DrillSpec
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

PILOT = DrillSpec(diameter_mm=2.0, tip_length_mm=0.6)
FINAL = DrillSpec(diameter_mm=2.8)  # the tip rule: 0.8 mm, as the implant's protocol


def test_sequence_plan_in_the_window(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    assert window.plan is not None
    assert window.plan_panel.sequence.text() == "2"
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.doc.set_plan(window.plan.with_drills((PILOT, FINAL)))
    assert window.plan_panel.sequence.text() == "2 -> 2.8"
    assert window.view is not None
    result = window.view.result
    assert result.plan.drill == FINAL and len(result.inner_holes) == 1
    assert result.inner_holes[0].radius_mm == 1.0
    note = f"(drill 2, 2.8 mm, after 2 mm to {result.inner_holes[0].depth_mm:.2f} mm)"
    assert note in window.rehearsal.auto_stop_label.text()
    # the diameter field edits the final drill; narrower than the pilot is refused
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.plan_panel.diameter.setValue(3.0)
    assert [d.diameter_mm for d in window.plan.drills] == [2.0, 3.0]
    with qtbot.waitSignal(window.doc.edit_refused, timeout=LOAD_TIMEOUT_MS) as refused:
        window.plan_panel.diameter.setValue(1.5)
    assert "must be larger than drills[0].diameter_mm" in refused.args[0]
    assert [d.diameter_mm for d in window.plan.drills] == [2.0, 3.0]
    assert np.isclose(window.plan_panel.diameter.value(), 3.0)


def test_the_drill_sequence_is_edited_in_the_window(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    box = window.plan_panel.sequence
    box.setText("2, 2.8 -> 3.5")
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        box.editingFinished.emit()
    assert window.plan is not None
    assert [d.diameter_mm for d in window.plan.drills] == [2.0, 2.8, 3.5]
    assert window.view is not None and len(window.view.result.inner_holes) == 2
    assert window.undo_action.text() == "Undo change drill"
    box.setText("3 -> 2")  # narrowing: refused, the sequence shown again
    with qtbot.waitSignal(window.doc.edit_refused, timeout=LOAD_TIMEOUT_MS) as refused:
        box.editingFinished.emit()
    assert "must be larger" in refused.args[0]
    assert box.text() == "2 -> 2.8 -> 3.5"
