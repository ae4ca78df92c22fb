"""The main window under Xvfb: open the phantom, edit the plan, see the results follow."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QSettings, Qt
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging.phantom.io import PhantomCase
from ctdrill.imaging.plan.load import load_plan
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case
from tests.app.gui.plot_marks import painted, vertical_marks_mm
from tests.imaging.slicer_files import slicer_save, validate_markups

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def plot_stop_lines(win: MainWindow) -> list[float]:
    """Depth of the stop line (magenta, solid) on each of the three plot axes, read from the
    plot's pixels (to a pixel and a half: under 0.02 mm)."""
    img, layout = painted(win.plot_canvas)
    tol = 1.5 * (layout.depth_at(layout.frames[0].x0 + 1.0) - layout.depth_at(layout.frames[0].x0))
    assert tol < 0.02
    return [x for marks in vertical_marks_mm(img, layout, "stop") for x in marks]


def test_window_opens_large_enough(window: MainWindow) -> None:
    assert window.width() >= 1280 and window.height() >= 800


def test_open_the_phantom_stops_at_the_true_safe_depth(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    truth = json.loads(phantom_case.truth_path.read_text())
    assert window.view is not None
    curves = window.view.curves
    assert curves.stop_reason == "margin"
    assert curves.stop_depth_mm == pytest.approx(truth["max_safe_depth_mm"], abs=0.01)
    # the plan places an implant: the drill reaches its apex (the target) plus its tip
    assert window.plan is not None and window.plan.implant is not None
    tip = window.plan.drill.tip_length_mm
    assert curves.planned_depth_mm == pytest.approx(truth["planned_depth_mm"] + tip)
    assert plot_stop_lines(window) == pytest.approx([curves.stop_depth_mm] * 3, abs=0.02)
    # The trabecular bone's force shows on the plot: D2 bone, well above air.
    mid = (curves.depth_mm > 4.0) & (curves.depth_mm < 8.0)
    assert np.all(curves.force_n[mid] > 1.0)
    assert set(window.slices) == {"axial", "coronal", "sagittal", "trajectory"}
    assert "error" not in window.statusBar().currentMessage()
    assert window.recent_folders()[0] == str(phantom_case.ct_dir)
    assert window.rehearsal.connect_button.isEnabled()


def test_moving_the_target_recomputes_the_plots_and_the_stop(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    assert window.plan is not None
    target = window.plan.target_lps + np.array([0.0, 0.0, 6.0])  # 6 mm up: depth 6 mm
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.slice_canvases["coronal"].point_moved.emit("target", target)
    assert window.view is not None
    assert window.view.curves.stop_reason == "planned_depth"
    # the implant's apex 6 mm down, the drill's tip beyond it
    assert window.view.curves.stop_depth_mm == pytest.approx(6.0 + window.plan.drill.tip_length_mm)
    assert plot_stop_lines(window) == pytest.approx(
        [6.0 + window.plan.drill.tip_length_mm] * 3, abs=0.02
    )
    # canal top at z = -43 + 1.2; the apex at z = -35, the tip 0.6 mm below: 6.2 mm clear
    assert window.view.min_clearance_mm is not None
    assert float(window.view.min_clearance_mm[0]) == pytest.approx(6.2, abs=0.02)
    assert window.plan_panel.point_boxes["target"][2].value() == pytest.approx(-35.0)


def test_dragging_the_target_moves_the_implant_whole_and_shift_slides_it(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    canvas = window.slice_canvases["trajectory"]
    assert window.plan is not None and canvas.image is not None
    old = window.plan
    uv, _ = canvas.image.to_plane_mm(old.target_lps)
    new_uv = uv + np.array([0.0, -4.0])  # 4 mm up the image = 4 mm back along the drill
    ratio = canvas.devicePixelRatioF()

    def qt_point(uv_mm: np.ndarray) -> QPoint:
        x, y = canvas.ax.transData.transform(uv_mm)
        return QPoint(round(x / ratio), round(canvas.height() - y / ratio))

    def drag(a: np.ndarray, b: np.ndarray, mods: Qt.KeyboardModifier) -> None:
        with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
            qtbot.mousePress(canvas, Qt.MouseButton.LeftButton, mods, qt_point(a))
            qtbot.mouseMove(canvas, qt_point((a + b) / 2))
            qtbot.mouseMove(canvas, qt_point(b))
            qtbot.mouseRelease(canvas, Qt.MouseButton.LeftButton, mods, qt_point(b))

    drag(uv, new_uv, Qt.KeyboardModifier.NoModifier)
    pixel = 0.4 * 1.5  # a pixel of slack either way
    moved = window.plan.target_lps - old.target_lps
    assert moved[2] == pytest.approx(4.0, abs=pixel)
    np.testing.assert_allclose(window.plan.entry_lps - old.entry_lps, moved, atol=1e-9)
    assert window.plan.planned_depth_mm == pytest.approx(old.planned_depth_mm)
    assert window.undo_action.text() == "Undo move implant"
    window.undo_action.trigger()
    assert window.plan is old
    # Shift: the apex slides along the axis, the entry stays: 4 mm shallower
    drag(uv, new_uv, Qt.KeyboardModifier.ShiftModifier)
    np.testing.assert_array_equal(window.plan.entry_lps, old.entry_lps)
    assert window.plan.planned_depth_mm == pytest.approx(old.planned_depth_mm - 4.0, abs=pixel)
    assert window.undo_action.text() == "Undo slide implant along its axis"


def test_numeric_edit_and_margin_change_the_stop(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    table = window.plan_panel.table
    margin_box = table.cellWidget(0, 2)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        margin_box.setValue(3.0)  # type: ignore[attr-defined]
    assert window.view is not None
    assert window.view.curves.stop_depth_mm == pytest.approx(9.8, abs=0.01)
    assert window.view.curves.margin_mm == pytest.approx(3.0)
    assert table.cellWidget(0, 2) is margin_box  # the row was updated, not rebuilt
    drills = table.item(0, 4)  # the planned clearance stays; the stop follows the margin
    assert drills.text().endswith(" 0.2 mm") and "at its stop: 3.0 mm" in drills.toolTip()
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        margin_box.setValue(2.5)  # type: ignore[attr-defined]
    assert window.view.curves.stop_depth_mm == pytest.approx(10.3, abs=0.01)
    # The feed spin box: the force scales by (1 + Ke v) / (1 + Ke v0), Ke = 0.25 per mm/s.
    f0 = window.view.curves.force_n.copy()
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.plan_panel.feed.setValue(2.0)
    ratio = (1.0 + 0.25 * 2.0) / (1.0 + 0.25 * 0.4)
    assert np.allclose(window.view.curves.force_n, f0 * ratio)


def test_save_and_reload_the_plan(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    assert window.plan is not None
    moved = window.plan.target_lps + np.array([1.0, -0.5, 2.0])
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.slice_canvases["axial"].point_moved.emit("target", moved)
    for name in ("plan.json", "plan.mrk.json"):
        window.save_plan(tmp_path / name)
        if name.endswith(".mrk.json"):
            validate_markups(json.loads((tmp_path / name).read_text(encoding="utf-8")))
        back = load_plan(tmp_path / name)
        assert np.allclose(back.target_lps, moved)
        assert np.allclose(back.entry_lps, window.plan.entry_lps)
        assert len(back.landmarks) == 1
    window.doc.set_plan(None)
    # After a 3D Slicer load and save: one markup per file, opened together.
    split = tmp_path / "slicer"
    split.mkdir()
    files = slicer_save(tmp_path / "plan.mrk.json", split)
    assert len(files) == 3  # the Line, the canal's Curve, the arch's Curve
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_plan(files)
    assert np.allclose(window.plan.target_lps, moved)
    assert len(window.plan.landmarks) == 1
    assert window.plan.arch_lps is not None and window.plan.implant is not None


def test_a_bad_folder_is_reported_not_raised(
    qtbot: QtBot, window: MainWindow, tmp_path: Path
) -> None:
    (tmp_path / "notes.txt").write_text("not dicom")
    window.open_folder(tmp_path)
    qtbot.waitUntil(lambda: window.load_error is not None, timeout=LOAD_TIMEOUT_MS)
    assert window.statusBar().currentMessage().startswith("error:")
    assert window.volume is None


def test_recent_folders_persist(tmp_path: Path, window: MainWindow) -> None:
    for i in range(10):
        window._remember(f"/data/{i}")
    again = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    assert again.value("recent_folders")[:2] == ["/data/9", "/data/8"]
    assert len(window.recent_folders()) == 8
    assert window.recent_menu.actions()[0].text() == "/data/9"


def test_a_new_series_opens_without_a_trajectory_until_one_is_placed(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    with qtbot.waitSignal(window.slices_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(phantom_case.ct_dir)
    assert window.plan is None and window.view is None  # nothing guessed
    assert "right-click the target" in window.statusBar().currentMessage()
    assert not window.rehearsal.connect_button.isEnabled()
    assert "no trajectory" in window.rehearsal.message.text()
    assert set(window.slices) == {"axial", "coronal", "sagittal"}
    traj = window.slice_canvases["trajectory"]
    assert traj.image is None and "no trajectory" in traj._note.get_text()
    # the bone surface drawn (on the 3D view's render thread), no drill
    qtbot.waitUntil(lambda: "bone" in window.view3d.actors, timeout=LOAD_TIMEOUT_MS)
    assert "drill" not in window.view3d.actors
    truth = json.loads(phantom_case.truth_path.read_text())
    plan = load_plan(phantom_case.plan_path)
    window.slice_canvases["axial"].point_moved.emit("target", plan.target_lps)
    assert window.plan is None and set(window.doc.draft) == {"target"}
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.slice_canvases["coronal"].point_moved.emit("entry", plan.entry_lps)
    assert window.plan is not None and window.view is not None
    assert np.allclose(window.plan.target_lps, plan.target_lps)
    assert window.view.curves.planned_depth_mm == pytest.approx(truth["planned_depth_mm"])
    assert window.view.curves.stop_reason == "planned_depth"  # no landmarks placed yet
    assert window.rehearsal.connect_button.isEnabled()


def test_a_plan_that_cannot_be_read_is_an_error_dialog(
    qtbot: QtBot,
    window: MainWindow,
    phantom_case: PhantomCase,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from PySide6.QtWidgets import QMessageBox

    open_case(qtbot, window, phantom_case)
    shown = window.plan
    dialogs: list[tuple[str, str]] = []
    monkeypatch.setattr(
        QMessageBox, "warning", lambda _parent, title, text: dialogs.append((title, text))
    )
    window.unattended = False
    bad = tmp_path / "typo.json"
    bad.write_text(phantom_case.plan_path.read_text().replace('"entry_mm"', '"entri_mm"'))
    assert not window.open_plan(bad)
    window.unattended = True
    assert len(dialogs) == 1 and "entri_mm" in dialogs[0][1] and "typo.json" in dialogs[0][1]
    assert window.plan is shown  # the plan shown stays; no default replaces it
    assert window.statusBar().currentMessage().startswith("error:")
