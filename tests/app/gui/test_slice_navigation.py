"""Paging through the slices, window/level, HU at the cursor, centring on the drill and the
distance tool, driven with keys and the mouse, on the demo phantom and on real CT.

Screenshots go to ``$CTDRILL_SLICE_SHOTS`` when set (to look at them), else to ``tmp_path``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.slice_nav import WL_HU_PER_PX, cursor_text, slice_stack
from ctdrill.app.gui.slice_view import SliceCanvas
from ctdrill.app.gui.slices import window_to_uint8
from ctdrill.imaging import load_series
from ctdrill.imaging.display import WINDOW_PRESETS
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"
GE_TILT = "dcmqa_ct_GE_head_gantrytilt_varspacing"


def shots(tmp_path: Path) -> Path:
    out = Path(os.environ.get("CTDRILL_SLICE_SHOTS", tmp_path))
    out.mkdir(parents=True, exist_ok=True)
    return out


def qt_point(canvas: SliceCanvas, uv_mm: np.ndarray) -> QPoint:
    """Widget coordinates of in-plane mm ``uv_mm`` on ``canvas``."""
    ratio = canvas.devicePixelRatioF()
    x, y = canvas.ax.transData.transform(uv_mm)
    return QPoint(round(x / ratio), round(canvas.height() - y / ratio))


def wheel(canvas: SliceCanvas, pos: QPoint, clicks: int, *, ctrl: bool = False) -> None:
    mods = Qt.KeyboardModifier.ControlModifier if ctrl else Qt.KeyboardModifier.NoModifier
    QApplication.sendEvent(
        canvas,
        QWheelEvent(
            QPointF(pos),
            QPointF(canvas.mapToGlobal(pos)),
            QPoint(0, 0),
            QPoint(0, 120 * clicks),
            Qt.MouseButton.NoButton,
            mods,
            Qt.ScrollPhase.NoScrollPhase,
            False,
        ),
    )


def open_series(qtbot: QtBot, window: MainWindow, folder: Path) -> None:
    with qtbot.waitSignal(window.slices_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(folder)
    settle(qtbot, window)


def settle(qtbot: QtBot, window: MainWindow) -> None:
    """Wait until every plane asked for is drawn."""
    qtbot.waitUntil(
        lambda: not window.slice_grid.runner.busy and window.ui_steps.pending == 0,
        timeout=LOAD_TIMEOUT_MS,
    )


def test_real_ct_opens_whole_and_pages_through_its_true_slices(
    qtbot: QtBot, window: MainWindow, shared_data: Path, tmp_path: Path
) -> None:
    window.resize(1440, 900)
    open_series(qtbot, window, shared_data / PHILIPS)
    vol = window.volume
    assert vol is not None
    grid, canvas = window.slice_grid, window.slice_canvases["axial"]
    assert canvas.image is not None
    left, right, bottom, top = canvas.image.extent_mm
    assert canvas.ax.get_xlim() == pytest.approx((left, right))  # the whole volume in view
    assert canvas.ax.get_ylim() == pytest.approx((bottom, top))
    # 28 slices of 5 mm from z = 696.21: the middle one (index 14) on open
    z0 = float(vol.affine_lps[2, 3])
    assert grid.positions["axial"] == pytest.approx(z0 + 14 * 5.0)
    assert canvas.position_text() == f"z {z0 + 70:.2f} mm · slice 15/28"
    np.testing.assert_array_equal(canvas.image.hu, vol.hu[14])  # the slice itself
    assert canvas.letters() == {"left": "R", "right": "L", "top": "A", "bottom": "P"}
    settle(qtbot, window)
    window.grab().save(str(shots(tmp_path) / "philips_open.png"))
    # PageUp, Up, the wheel: one slice each, through the real positions
    canvas.setFocus()
    qtbot.keyClick(canvas, Qt.Key.Key_PageUp)
    settle(qtbot, window)
    assert grid.positions["axial"] == pytest.approx(z0 + 75.0)
    np.testing.assert_array_equal(canvas.image.hu, vol.hu[15])
    assert canvas.position_text().endswith("slice 16/28")
    qtbot.keyClick(canvas, Qt.Key.Key_Up)
    wheel(canvas, QPoint(canvas.width() // 2, canvas.height() // 2), -3)
    qtbot.keyClick(canvas, Qt.Key.Key_PageDown)
    settle(qtbot, window)
    assert grid.positions["axial"] == pytest.approx(z0 + 60.0)  # 15 + 1 - 3 - 1 = 12
    np.testing.assert_array_equal(canvas.image.hu, vol.hu[12])
    for _ in range(40):  # clamped at the first slice
        qtbot.keyClick(canvas, Qt.Key.Key_Down)
    settle(qtbot, window)
    assert canvas.position_text() == f"z {z0:.2f} mm · slice 1/28"
    # The coronal view pages through the rows (0.451 mm apart)
    cor = window.slice_canvases["coronal"]
    before = grid.positions["coronal"]
    qtbot.keyClick(cor, Qt.Key.Key_PageUp)
    settle(qtbot, window)
    assert grid.positions["coronal"] - before == pytest.approx(vol.spacing_mm[1])
    assert "row" in cor.position_text()


def test_window_level_drag_presets_and_hu_at_the_cursor(
    qtbot: QtBot, window: MainWindow, shared_data: Path, tmp_path: Path
) -> None:
    open_series(qtbot, window, shared_data / PHILIPS)
    vol, grid = window.volume, window.slice_grid
    canvas = window.slice_canvases["axial"]
    assert vol is not None and canvas.image is not None
    assert grid.wl_label.text() == "W 2000 L 500"
    # right-drag 50 px right and 20 px down: width +200, level +80
    start = QPoint(canvas.width() // 2, canvas.height() // 2)
    qtbot.mousePress(canvas, Qt.MouseButton.RightButton, pos=start)
    qtbot.mouseMove(canvas, start + QPoint(25, 10))
    qtbot.mouseMove(canvas, start + QPoint(50, 20))
    qtbot.mouseRelease(canvas, Qt.MouseButton.RightButton, pos=start + QPoint(50, 20))
    level, width = 500.0 + 20 * WL_HU_PER_PX, 2000.0 + 50 * WL_HU_PER_PX
    assert grid.window_level == pytest.approx((level, width))
    assert grid.wl_label.text() == f"W {width:.0f} L {level:.0f}"
    shown = np.asarray(canvas._im.get_array())
    np.testing.assert_array_equal(
        shown, window_to_uint8(canvas.image.hu, level_hu=level, width_hu=width)
    )
    assert window.plan is None  # a drag is not a click: no target placed
    # the preset box
    grid.toolbar.preset.textActivated.emit("soft tissue")
    assert grid.window_level == WINDOW_PRESETS["soft tissue"] == (40.0, 400.0)
    assert grid.wl_label.text() == "W 400 L 40"
    # HU at the cursor: a voxel centre reads the voxel, with its LPS position
    settle(qtbot, window)
    qtbot.wait(200)  # the layout after the window/level changes
    k, j, i = 14, 300, 200
    p = vol.index_to_lps(np.array([i, j, k], dtype=float))
    uv, off = canvas.image.to_plane_mm(p)
    assert abs(float(off)) < 1e-9

    def over_the_voxel() -> bool:
        """The mouse moved (again) onto the voxel at the canvas' current layout: a late
        layout under load moves the image after the point was computed."""
        at = qt_point(canvas, canvas.image.to_plane_mm(p)[0] if canvas.image else uv)
        qtbot.mouseMove(canvas, at + QPoint(1, 0))
        qtbot.mouseMove(canvas, at)
        return grid.readout.text().startswith("HU ")

    qtbot.waitUntil(over_the_voxel, timeout=LOAD_TIMEOUT_MS)
    text = grid.readout.text()
    hu, x, y, z = (float(text.split()[i]) for i in (1, 4, 6, 8))
    mm_per_px = abs(np.diff(canvas.ax.get_xlim())[0]) / canvas.ax.bbox.width
    # the point under the cursor (to a pixel), on the slice, read there
    assert abs(x - p[0]) <= 1.5 * mm_per_px and abs(y - p[1]) <= 1.5 * mm_per_px
    assert z == pytest.approx(round(p[2], 1))
    here = np.array([x, y, p[2]])
    assert abs(hu - float(vol.sample(here[None, :])[0])) <= 1.0 + np.ptp(
        vol.hu[14, j - 3 : j + 4, i - 3 : i + 4]
    )
    assert cursor_text(vol, p) == (
        f"HU {int(vol.hu[k, j, i])} at L {p[0]:.1f} P {p[1]:.1f} S {p[2]:.1f} mm"
    )
    grid.set_window_preset("bone")
    settle(qtbot, window)
    window.grab().save(str(shots(tmp_path) / "philips_cursor.png"))


def test_the_tilted_head_is_sampled_exactly_and_padding_reads_outside(
    qtbot: QtBot, window: MainWindow, shared_data: Path, tmp_path: Path
) -> None:
    open_series(qtbot, window, shared_data / GE_TILT)
    vol, grid = window.volume, window.slice_grid
    assert vol is not None and not vol.regular
    # the tilted slices are not axial: the axial view steps one voxel and says so; the
    # sagittal view pages through the columns
    assert not grid.stacks["axial"].real and grid.stacks["sagittal"].label == "column"
    assert "oblique to the slices" in window.slice_canvases["axial"].position_text()
    # keys faster than the planes are resliced: the view ends on the last plane asked for
    axial = window.slice_canvases["axial"]
    start = grid.positions["axial"]
    for _ in range(6):
        qtbot.keyClick(axial, Qt.Key.Key_PageUp)
    settle(qtbot, window)
    assert grid.positions["axial"] == pytest.approx(grid.stacks["axial"].step(start, 6))
    assert axial.image is not None
    assert axial.image.origin_lps[2] == pytest.approx(grid.positions["axial"], abs=1e-9)
    assert axial.position_text() == grid.stacks["axial"].describe(grid.positions["axial"])
    for view in ("axial", "coronal", "sagittal"):
        canvas = window.slice_canvases[view]
        img = canvas.image
        assert img is not None
        qtbot.keyClick(canvas, Qt.Key.Key_PageUp)
        settle(qtbot, window)
        img = canvas.image
        assert img is not None
        axis = grid.stacks[view].axis
        rows, cols = np.meshgrid(
            np.arange(0, img.hu.shape[0], 37), np.arange(0, img.hu.shape[1], 41)
        )
        uv = np.stack([cols.ravel(), rows.ravel()], axis=-1) * img.pixel_mm
        pts = img.to_lps(uv)
        # every pixel lies on the plane the readout names, and shows the volume's trilinear
        # value there (true slice positions), air outside
        np.testing.assert_allclose(pts[:, axis], grid.positions[view], atol=1e-9)
        want = vol.sample(pts)
        got = img.hu[rows.ravel(), cols.ravel()]
        np.testing.assert_allclose(got, want, atol=1e-3)
    # the padding (-1500 stored) reads "outside", never a number
    padded = np.argwhere(~vol.valid[10])  # type: ignore[index]
    j, i = padded[len(padded) // 2]
    p = vol.index_to_lps(np.array([i, j, 10], dtype=float))
    assert cursor_text(vol, p).startswith("outside the volume at L ")
    settle(qtbot, window)
    window.grab().save(str(shots(tmp_path) / "ge_tilt.png"))


def test_stacks_of_real_series_hold_their_true_positions(shared_data: Path) -> None:
    ge = load_series(str(shared_data / GE_TILT))
    sag = slice_stack(ge, "sagittal")
    assert sag.real and sag.count == ge.hu.shape[2]
    np.testing.assert_allclose(np.diff(sag.positions_mm), ge.spacing_mm[0], rtol=1e-12)
    ax = slice_stack(ge, "axial")
    assert not ax.real and ax.label == "step"
    np.testing.assert_allclose(np.diff(ax.positions_mm), ge.affine_lps[2, 2], rtol=1e-12)
    ph = load_series(str(shared_data / PHILIPS))
    st = slice_stack(ph, "axial")
    np.testing.assert_allclose(st.positions_mm, ph.affine_lps[2, 3] + 5.0 * np.arange(28))
    assert st.step(float(st.positions_mm[3]) + 1.0, 1) == st.positions_mm[4]
    assert st.step(float(st.positions_mm[3]) + 1.0, -1) == st.positions_mm[3]
    assert st.step(float(st.positions_mm[3]), -2) == st.positions_mm[1]
    assert st.describe(float(st.positions_mm[3]) + 1.0).endswith("between slices 4 and 5")


def test_centre_on_the_drill_and_measure_a_distance_on_the_demo(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    window.resize(1440, 900)
    open_case(qtbot, window, phantom_case)
    settle(qtbot, window)
    grid, plan = window.slice_grid, window.plan
    assert plan is not None
    # opened through the target, the whole plane in view
    for view in ("axial", "coronal", "sagittal"):
        assert grid.positions[view] == pytest.approx(plan.target_lps[grid.stacks[view].axis])
    axial = window.slice_canvases["axial"]
    for _ in range(5):
        qtbot.keyClick(axial, Qt.Key.Key_PageDown)
    settle(qtbot, window)
    assert grid.positions["axial"] != pytest.approx(plan.target_lps[2])
    qtbot.keyClick(axial, Qt.Key.Key_C)  # centre on the drill
    settle(qtbot, window)
    assert grid.positions["axial"] == pytest.approx(plan.target_lps[2])
    # the distance tool: two clicks on the coronal view; the exact LPS length is drawn
    grid.toolbar.tool_buttons["distance"].click()
    cor = window.slice_canvases["coronal"]
    assert cor.mode == "distance" and cor.image is not None
    a_uv, b_uv = np.array([8.0, 6.0]), np.array([20.0, 15.0])
    for uv in (a_uv, b_uv):
        qtbot.mouseClick(cor, Qt.MouseButton.LeftButton, pos=qt_point(cor, uv))
    ends = cor.tools.measure_lps
    assert len(ends) == 2
    _, off = cor.image.to_plane_mm(np.array(ends))
    np.testing.assert_allclose(off, 0.0, atol=1e-9)
    length = float(np.linalg.norm(ends[1] - ends[0]))
    assert cor.tools.length_mm == pytest.approx(length, abs=1e-12)
    assert length == pytest.approx(15.0, abs=0.3)  # 12 x 9 mm apart, to a pixel
    labels = [t.get_text() for t in cor.ax.texts]
    assert f" {length:.2f} mm" in labels
    settle(qtbot, window)
    window.grab().save(str(shots(tmp_path) / "demo_distance.png"))
    qtbot.keyClick(cor, Qt.Key.Key_Delete)
    assert cor.tools.length_mm is None and not [t for t in cor.ax.texts if "mm" in t.get_text()]
    for uv in (a_uv, b_uv):
        qtbot.mouseClick(cor, Qt.MouseButton.LeftButton, pos=qt_point(cor, uv))
    assert cor.tools.length_mm is not None
    qtbot.mouseClick(cor, Qt.MouseButton.RightButton, pos=qt_point(cor, a_uv))
    assert cor.tools.length_mm is None
    assert window.plan is plan  # the right click removed the measurement, placed nothing
    # the drill view turns about the drill
    traj = window.slice_canvases["trajectory"]
    qtbot.keyClick(traj, Qt.Key.Key_PageUp)
    settle(qtbot, window)
    assert traj.position_text() == "turned +15° about the drill"


def test_a_trajectory_placed_on_real_ct_is_drawn_as_the_drill(
    qtbot: QtBot, window: MainWindow, shared_data: Path, tmp_path: Path
) -> None:
    window.resize(1440, 900)
    open_series(qtbot, window, shared_data / PHILIPS)
    grid = window.slice_grid
    ax, cor = window.slice_canvases["axial"], window.slice_canvases["coronal"]
    assert ax.image is not None and cor.image is not None
    # target: right click on the axial slice; entry: Shift + right click on the coronal, 20 mm
    # above the target
    # (on the coronal plane shown, so the drill lies in it)
    target_uv = np.array([115.0, grid.positions["coronal"] - ax.image.origin_lps[1]])
    qtbot.mouseClick(ax, Qt.MouseButton.RightButton, pos=qt_point(ax, target_uv))
    target = window.doc.draft["target"]
    assert target[2] == pytest.approx(grid.positions["axial"])
    assert target[1] == pytest.approx(grid.positions["coronal"], abs=ax.image.pixel_mm)
    target[1] = grid.positions["coronal"]
    entry = target + np.array([0.0, 0.0, 20.0])
    e_uv, off = cor.image.to_plane_mm(entry)
    assert abs(float(off)) < 1e-9
    qtbot.mouseClick(
        cor,
        Qt.MouseButton.RightButton,
        Qt.KeyboardModifier.ShiftModifier,
        pos=qt_point(cor, e_uv),
    )
    plan = window.plan
    assert plan is not None
    settle(qtbot, window)
    # a trajectory appeared: the planes go through its target; the drill is drawn on them
    for view in ("axial", "coronal", "sagittal"):
        assert grid.positions[view] == pytest.approx(plan.target_lps[grid.stacks[view].axis])
    assert cor.ax.patches and window.slice_canvases["sagittal"].ax.patches
    # the axial plane through the target meets only the drill's tip point: nothing to fill;
    # one slice up (5 mm) it cuts the vertical drill in a circle of the drill's radius
    assert not ax.ax.patches
    qtbot.keyClick(ax, Qt.Key.Key_PageUp)
    settle(qtbot, window)
    assert grid.positions["axial"] == pytest.approx(plan.target_lps[2] + 5.0)
    (circle,) = [np.asarray(p.get_xy()) for p in ax.ax.patches]
    # the clicks land within a screen pixel, so the drill may lean by a few hundredths of a
    # degree: the cut is centred on its axis 5 mm up, and stretched by at most 1 / cos(tilt)
    up = -plan.direction
    centre, _ = ax.image.to_plane_mm(plan.target_lps + up * (5.0 / up[2]))
    stretch = plan.drill.radius_mm * (1.0 / up[2] - 1.0)
    radii = np.hypot(*(circle - centre).T)
    np.testing.assert_allclose(radii, plan.drill.radius_mm, atol=stretch + 1e-9)
    traj = window.slice_canvases["trajectory"]
    assert traj.image is not None and traj.ax.patches
    qtbot.waitUntil(lambda: window.view is not None, timeout=LOAD_TIMEOUT_MS)
    settle(qtbot, window)
    window.grab().save(str(shots(tmp_path) / "philips_trajectory.png"))
