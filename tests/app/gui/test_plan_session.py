"""A planning session in the window: several trajectories, the current one's path, undo/redo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def wait_path(qtbot: QtBot, window: MainWindow) -> None:
    qtbot.waitUntil(
        lambda: window.view is not None and window.view.plan is window.plan,
        timeout=LOAD_TIMEOUT_MS,
    )


def test_add_select_rename_remove_trajectories_and_undo_each(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    doc, tl = window.doc, window.plan_panel.trajectories
    first = window.plan
    assert first is not None and tl.list.count() == 1
    first_view = window.view
    assert window.undo_action.text() == "Undo" and not window.undo_action.isEnabled()

    tl.add.click()  # a copy 8 mm to the patient's left (the phantom plan has no arch)
    assert len(doc.plans) == 2 and doc.current == 1 and tl.list.currentRow() == 1
    second = doc.plans[1]
    assert np.allclose(second.entry_lps - first.entry_lps, [8.0, 0.0, 0.0])
    assert second.name == "implant 1" and second.drill == first.drill
    assert window.undo_action.text() == "Undo add trajectory 'implant 1'"
    wait_path(qtbot, window)  # the new current trajectory's path is computed
    second_view = window.view
    assert second_view is not None and second_view is not first_view

    tl.list.setCurrentRow(0)  # selecting shows the path already computed, at once
    assert window.plan is first and window.view is first_view
    assert window.plan_panel.point_boxes["entry"][0].value() == pytest.approx(first.entry_lps[0])
    tl.list.setCurrentRow(1)
    assert window.view is second_view

    assert tl.rename_current("36")
    assert window.plan is not None and window.plan.name == "36"
    assert tl.list.item(1).text().startswith("2. 36  (")
    assert not tl.rename_current("") and not tl.rename_current(first.name)  # refused
    assert window.undo_action.text() == "Undo rename trajectory"

    moved = window.plan.target_lps + np.array([0.0, 0.0, 1.0])
    window.slice_canvases["coronal"].point_moved.emit("target", moved)
    assert window.undo_action.text() == "Undo move target"
    window.plan_panel.diameter.setValue(3.0)
    assert window.undo_action.text() == "Undo change drill"

    tl.remove.click()
    assert len(doc.plans) == 1 and window.plan is first
    assert window.undo_action.text() == "Undo remove trajectory '36'"

    expected = [
        ("remove trajectory '36'", 2),
        ("change drill", 2),
        ("move target", 2),
        ("rename trajectory", 2),
        ("add trajectory 'implant 1'", 1),
    ]
    for name, count in expected:  # Edit > Undo, as the menu item does it
        assert window.undo_action.text() == f"Undo {name}"
        window.undo_action.trigger()
        assert len(doc.plans) == count and tl.list.count() == count
    assert doc.plans == (first,) and not window.undo_action.isEnabled()
    assert window.redo_action.text() == "Redo add trajectory 'implant 1'"
    for _ in expected:
        window.redo_action.trigger()
    assert [p.name for p in doc.plans] == [first.name]
    assert window.plan is first
    window.activateWindow()
    qtbot.waitUntil(lambda: QApplication.activeWindow() is window, timeout=5000)
    qtbot.keyClick(
        window.plan_panel.trajectories.list, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier
    )
    assert len(doc.plans) == 2  # Ctrl+Z undid the removal
