"""Window interactions: drop a folder or a plan, presets, canal points, right-click placing."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.slice_view import SliceCanvas
from ctdrill.app.gui.slices import window_to_uint8
from ctdrill.imaging.phantom.io import PhantomCase
from ctdrill.imaging.plan.landmarks import CanalLandmark
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def qt_point(canvas: SliceCanvas, uv_mm: np.ndarray) -> QPoint:
    """Widget coordinates of in-plane mm ``uv_mm`` on ``canvas``."""
    ratio = canvas.devicePixelRatioF()
    x, y = canvas.ax.transData.transform(uv_mm)
    return QPoint(round(x / ratio), round(canvas.height() - y / ratio))


def test_dropping_a_dicom_file_opens_its_folder_and_a_json_opens_the_plan(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    window.open_dropped(str(phantom_case.plan_path))
    assert window.plan is not None and window.plan.name == "plan"
    one_file = next(phantom_case.ct_dir.iterdir())
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_dropped(str(one_file))
    assert window.volume_path == str(phantom_case.ct_dir)


def test_window_preset_rewindows_the_slices(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    image = window.slices["axial"]
    window.set_window_preset("soft tissue")
    shown = np.asarray(window.slice_canvases["axial"]._im.get_array())
    expected = window_to_uint8(image.hu, level_hu=40.0, width_hu=400.0)
    assert np.array_equal(shown, expected)


def test_surface_preset_recontours_in_the_background(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    assert window.view3d.surface is not None
    before = window.view3d.surface.n_points
    with qtbot.waitSignal(window.surface_updated, timeout=LOAD_TIMEOUT_MS):
        window.set_surface_preset(-300.0)  # the soft tissue around the bone: a larger surface
    assert window.view3d.surface is not None
    bounds_soft = np.array(window.view3d.surface.bounds)
    assert window.view3d.surface.n_points != before
    with qtbot.waitSignal(window.surface_updated, timeout=LOAD_TIMEOUT_MS):
        window.set_surface_preset(1000.0)  # cortical only
    bounds_cortex = np.array(window.view3d.surface.bounds)
    assert bounds_soft[5] > bounds_cortex[5]  # the soft tissue reaches higher than the bone


def test_canal_points_clicked_on_a_slice_trace_the_sides_canal(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    window.plan_panel.add_canal.setChecked(True)
    canvas = window.slice_canvases["coronal"]
    assert canvas.image is not None and window.plan is not None
    before = window.plan.landmarks
    (canal,) = before  # the phantom's left canal
    assert canal.name == "left mandibular canal"
    clicked = []
    for u in (10.0, 20.0):  # two points on the patient's left of x = 0 (a partial arch)
        uv = np.array([u, 15.0])
        clicked.append(canvas.image.to_lps(uv))
        with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
            qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=qt_point(canvas, uv))
    window.plan_panel.add_canal.setChecked(False)
    assert not canvas.add_points_mode
    assert all(p[0] > 0 for p in clicked)
    (traced,) = window.plan.landmarks  # the side's canal grew: no second canal
    assert isinstance(traced, CanalLandmark) and traced.name == "left mandibular canal"
    assert len(traced.points_lps) == len(canal.points_lps) + 2
    for p in clicked:  # each point where it was clicked (to a pixel)
        assert np.min(np.linalg.norm(traced.points_lps - p, axis=1)) < 0.4
    assert window.undo_action.text() == "Undo trace 'left mandibular canal'"
    window.undo_action.trigger()
    window.undo_action.trigger()
    assert window.plan.landmarks == before


def test_right_click_places_the_target(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    canvas = window.slice_canvases["sagittal"]
    assert canvas.image is not None and window.plan is not None
    goal = window.plan.target_lps + np.array([0.0, 2.0, 3.0])  # in the sagittal plane
    uv, off = canvas.image.to_plane_mm(goal)
    assert abs(float(off)) < 1e-9
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseClick(canvas, Qt.MouseButton.RightButton, pos=qt_point(canvas, uv))
    assert window.plan.target_lps == pytest.approx(goal, abs=0.4)


def test_slice_views_show_the_whole_plane_and_zoom_with_ctrl_wheel(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    canvas = window.slice_canvases["coronal"]
    assert canvas.image is not None and window.plan is not None
    left, right, bottom, top = canvas.image.extent_mm
    full = max(right - left, bottom - top)
    assert canvas.ax.get_xlim() == pytest.approx((left, right))  # the whole plane on open
    # One Ctrl+wheel step up over the entry point zooms in by 1.25 and keeps the entry under it.
    entry_uv, _ = canvas.image.to_plane_mm(window.plan.entry_lps)
    pos = qt_point(canvas, entry_uv)
    event = QWheelEvent(
        QPointF(pos),
        QPointF(canvas.mapToGlobal(pos)),
        QPoint(0, 0),
        QPoint(0, 120),
        Qt.MouseButton.NoButton,
        Qt.KeyboardModifier.ControlModifier,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    QApplication.sendEvent(canvas, event)
    x0, x1 = canvas.ax.get_xlim()
    y0, y1 = canvas.ax.get_ylim()
    assert x1 - x0 == pytest.approx(full / 1.25) and y0 - y1 == pytest.approx(full / 1.25)
    after = qt_point(canvas, entry_uv)  # the point under the cursor stays put (rounding: 1 px)
    assert abs(after.x() - pos.x()) <= 1 and abs(after.y() - pos.y()) <= 1
    # "-" zooms back out (by the same factor), "+" in again
    qtbot.keyClick(canvas, Qt.Key.Key_Minus)
    assert canvas.ax.get_xlim() == pytest.approx((left, right))
    qtbot.keyClick(canvas, Qt.Key.Key_Plus)
    x0, x1 = canvas.ax.get_xlim()
    assert x1 - x0 == pytest.approx(full / 1.25)
    # Centred on the trajectory at a chosen field of view, then all the way out.
    canvas.fov_mm = 20.0
    mid = (window.plan.entry_lps + window.plan.target_lps) / 2.0
    canvas.focus_on(mid)
    uv, _ = canvas.image.to_plane_mm(mid)
    x0, x1 = canvas.ax.get_xlim()
    assert (x1 - x0, (x0 + x1) / 2) == pytest.approx((20.0, uv[0]))
    canvas.zoom(1e-6)
    assert canvas.fov_mm is None
    assert canvas.ax.get_xlim() == pytest.approx((left, right))
