"""The window says what the outputs say (issue 25), driven with real clicks and keys: a second
implant typed onto the first shows ``implants_too_close`` in the banner and draws both
implants red in 3D and on the slices."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.patches import Polygon
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QDoubleSpinBox
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.scene import CLEARANCE_COLOURS, IMPLANT_COLOUR
from ctdrill.app.gui.slice_overlays import VIOLATED_COLOUR
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def type_value(qtbot: QtBot, box: QDoubleSpinBox, value: float) -> None:
    """Select the spin box's text, type ``value`` and press Enter, as a user does."""
    box.setFocus()
    qtbot.keyClick(box.lineEdit(), Qt.Key.Key_A, Qt.KeyboardModifier.ControlModifier)
    qtbot.keyClicks(box.lineEdit(), f"{value:.2f}")
    qtbot.keyClick(box.lineEdit(), Qt.Key.Key_Return)


def red_outlines(window: MainWindow, view: str) -> int:
    """Unfilled red polygons (implant outlines) on a slice view."""
    red = np.round(to_rgb(VIOLATED_COLOUR), 3)
    return sum(
        1
        for p in window.slice_canvases[view].ax.patches
        if isinstance(p, Polygon)
        and not p.get_fill()
        and np.array_equal(np.round(p.get_edgecolor()[:3], 3), red)
    )


def test_two_implants_typed_too_close_are_listed_and_drawn_red(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    window.resize(1440, 900)
    open_case(qtbot, window, phantom_case)
    first = window.plan
    assert first is not None
    panel = window.plan_panel
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseClick(panel.trajectories.add, Qt.MouseButton.LeftButton)  # 8 mm beside
    second = window.plan
    assert second is not first and len(window.doc.plans) == 2
    banner = window.views["banner"]
    assert "implants_too_close" not in banner.text()  # type: ignore[attr-defined]
    # type the second implant's entry and target 3 mm from the first: the 4.1 mm bodies overlap
    for name in ("entry", "target"):
        point = (first.entry_lps if name == "entry" else first.target_lps) + [3.0, 0.0, 0.0]
        for axis in (0, 1):  # x and y (the copy went 8 mm along the arch)
            box = panel.point_boxes[name][axis]
            if abs(box.value() - point[axis]) < 0.005:
                continue
            with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
                type_value(qtbot, box, float(point[axis]))
    qtbot.waitUntil(
        lambda: not window.slice_grid.runner.busy and window.ui_steps.pending == 0,
        timeout=LOAD_TIMEOUT_MS,
    )
    text = banner.text()  # type: ignore[attr-defined]
    assert banner.kind == "violation"  # type: ignore[attr-defined]
    assert "• implants too close (implants_too_close): implants of " in text
    assert window.view is not None
    close = [w.message for w in window.view.problems if w.code == "implants_too_close"]
    assert len(close) == 1 and close[0] in text  # the outputs' message, whole
    listed = window.views["series"].path_warnings_list  # type: ignore[attr-defined]
    rows = [listed.item(i).text() for i in range(listed.count())]
    assert rows.count(f"implants_too_close: {close[0]}") == 1  # the Series tab, once
    # both implants red in 3D (the first one, not current, too)
    violated = CLEARANCE_COLOURS["violated"]
    for key in ("implant:0", "implant:1"):
        colour = window.view3d.actors[key].GetProperty().GetColor()
        assert colour == pytest.approx(violated, abs=1 / 255)
        assert colour != pytest.approx(IMPLANT_COLOUR, abs=1 / 255)
    window.save_screenshot(tmp_path / "too_close.png")
    assert red_outlines(window, "trajectory") >= 2  # both bodies cut by the drill's plane
