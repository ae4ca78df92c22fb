"""The plan panel is shown again on every edit and every path result: only the fields whose
text changes repaint (a spin box or line edit set to what it shows repaints anyway, dozens of
widgets on every canal click), and the table's clearances wait as "unknown" until the path
result fills them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from PySide6.QtCore import QEvent, QObject
from PySide6.QtWidgets import QAbstractSpinBox, QLineEdit
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui


class _Paints(QObject):
    def __init__(self) -> None:
        super().__init__()
        self.painted: set[int] = set()

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        if event.type() == QEvent.Type.Paint:
            self.painted.add(id(obj))
        return False


def test_showing_the_plan_again_repaints_only_what_changed(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.plan_panel
    plan = window.plan
    assert plan is not None
    panel.set_plan(plan)  # as on an edit: its clearances "unknown" until its path result
    qtbot.wait(50)
    boxes = panel.findChildren(QAbstractSpinBox) + panel.findChildren(QLineEdit)
    paints = _Paints()
    for box in boxes:
        box.installEventFilter(paints)
    try:
        panel.set_plan(plan)  # shown again (the path result's turn): nothing to repaint
        qtbot.wait(50)
        assert {id(b) for b in boxes} & paints.painted == set()
        moved = replace(plan, target_lps=plan.target_lps + np.array([0.5, 0.0, 0.0]))
        panel.set_plan(moved)
        qtbot.wait(50)
        x_box = panel.point_boxes["target"][0]
        assert x_box.value() == pytest.approx(moved.target_lps[0], abs=0.01)
        assert id(x_box) in paints.painted
    finally:
        for box in boxes:
            box.removeEventFilter(paints)


def test_the_clearances_are_unknown_until_the_path_result_fills_them(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    plan = window.plan
    assert plan is not None
    table = window.plan_panel.table
    filled = [table.item(0, col).text() for col in (3, 4)]
    assert "unknown" not in filled
    moved = replace(plan, target_lps=plan.target_lps + np.array([0.3, 0.0, 0.0]))
    window.plan_panel.set_plan(moved)
    assert [table.item(0, col).text() for col in (3, 4)] == ["unknown", "unknown"]
    window.plan_panel.set_plan(moved)  # again: still unknown, the items kept
    kept = [table.item(0, col) for col in (3, 4)]
    window.plan_panel.set_plan(moved)
    assert [table.item(0, col) for col in (3, 4)] == kept
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.use_plan(moved)
    qtbot.waitUntil(lambda: table.item(0, 3).text() != "unknown", timeout=LOAD_TIMEOUT_MS)
    assert "unknown" not in [table.item(0, col).text() for col in (3, 4)]
