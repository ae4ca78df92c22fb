"""The margins in the window: the binding landmark's margin line, and the banner and marks
when the planned path breaks a margin (``plan_violates_margin``); the landmark table shows the
planned clearance (0.8 mm), not the clearance at the stop (the margin itself)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui import planning
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.problems import VIOLATED_MARK
from ctdrill.app.gui.scene import CLEARANCE_COLOURS
from ctdrill.app.gui.slice_overlays import VIOLATED_COLOUR
from ctdrill.imaging.phantom.io import PhantomCase
from ctdrill.imaging.plan.landmarks import PointLandmark
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case
from tests.app.gui.plot_marks import horizontal_marks, painted

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

CANAL = "left mandibular canal"


def margin_lines(win: MainWindow) -> list[float]:
    """Clearance (mm) of the dashed margin line on the clearance axis, read from the plot's
    pixels (to a pixel and a half of the axis)."""
    img, layout = painted(win.plot_canvas)
    return horizontal_marks(img, layout.frames[2], "margin_line")


def test_two_landmarks_the_plot_draws_the_binding_margin(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    plan = window.plan
    assert plan is not None
    # The canal below (margin 2.5 mm) sets the stop at 10.3 mm; a point 2 mm beside the axis
    # at z = -37 (margin 0.5 mm) is then 1.0 mm from the drill's side: nearer, not binding.
    plan = planning.set_landmark_margin(plan, 0, 2.5)
    apex = PointLandmark("apex", np.array([34.0, 10.0, -37.0]), margin_mm=0.5)
    plan = replace(plan, landmarks=(*plan.landmarks, apex))
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.use_plan(plan)
    view = window.view
    assert view is not None and view.curves.stop_reason == "margin"
    assert view.curves.stop_depth_mm == pytest.approx(10.3, abs=0.01)
    assert view.min_clearance_mm is not None
    at_stop = view.min_clearance_mm
    assert at_stop[1] == pytest.approx(1.0, abs=0.02) and at_stop[0] == pytest.approx(2.5, abs=0.01)
    assert int(np.argmin(at_stop)) == 1 and view.result.binding_landmark == 0  # nearer != binding
    assert view.curves.margin_mm == pytest.approx(2.5)
    assert margin_lines(window) == [pytest.approx(2.5, abs=0.4)]  # not the 0.5 mm one


def test_a_plan_through_the_margin_shows_a_banner_and_marks_the_landmark(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)  # target 0.8 mm above the canal: margin 2 mm broken
    assert window.view is not None
    codes = [w.code for w in window.view.result.warnings]
    assert codes.count("plan_violates_margin") == 2  # the drill's and the implant body's
    banner = window.views["banner"]
    assert banner.isVisible() and banner.kind == "violation"  # type: ignore[attr-defined]
    assert CANAL in banner.text()  # type: ignore[attr-defined]
    # The table: the planned clearances (0.4 mm voxels: +-0.2 mm, one decimal), not the
    # clearance at the stop (2.0 mm, the margin: it would read "safe"). The implant's round
    # apex sits 0.8 mm above the canal; the drill's tip 0.6 mm beyond it.
    implant, drills = (window.plan_panel.table.item(0, col) for col in (3, 4))
    assert implant.text() == f"{VIOLATED_MARK} 0.8 mm" and "implant breaks" in implant.toolTip()
    assert drills.text() == f"{VIOLATED_MARK} 0.2 mm" and "planned depth 12.60 mm" in (
        drills.toolTip()
    )
    assert "at its stop: 2.0 mm" in drills.toolTip()  # the margin stops the drill there
    assert "implant_violates_margin" in banner.text()  # type: ignore[attr-defined]
    qtbot.waitUntil(lambda: f"margin:{CANAL}" in window.view3d.actors, timeout=LOAD_TIMEOUT_MS)
    colour = window.view3d.actors[f"margin:{CANAL}"].GetProperty().GetColor()
    assert colour == pytest.approx(CLEARANCE_COLOURS["violated"], abs=1 / 255)
    canal_lines = [
        ln for ln in window.slice_canvases["coronal"].ax.lines if ln.get_color() == VIOLATED_COLOUR
    ]
    assert canal_lines
    # A target 6 mm higher keeps the margin: no banner, the canal is no longer marked.
    assert window.plan is not None
    target = window.plan.target_lps + np.array([0.0, 0.0, 6.0])
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.slice_canvases["coronal"].point_moved.emit("target", target)
    # The margins hold (nothing marked), but the 11.5 mm implant now stands above the entry
    # of a 6 mm path: the banner says that instead.
    text = banner.text()  # type: ignore[attr-defined]
    assert "margin" not in text.split("\n")[0] and "plan_violates_margin" not in text
    assert "(implant_above_entry): " in text
    assert window.plan_panel.table.item(0, 3).text() == "6.8 mm"
    assert window.plan_panel.table.item(0, 4).text() == "6.2 mm"
