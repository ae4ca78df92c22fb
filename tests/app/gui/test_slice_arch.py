"""The dental arch drawn and edited on the axial view, and the implant body drawn on the
slices, driven with the mouse and keys on the demo phantom."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.slice_overlays import IMPLANT_COLOUR, VIOLATED_COLOUR
from ctdrill.app.gui.slice_view import SliceCanvas
from ctdrill.imaging.phantom.io import PhantomCase
from ctdrill.imaging.plan.implants import implant_placement, load_implant_library
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case
from tests.app.gui.test_slice_drawing import _rgb
from tests.app.gui.test_slice_navigation import qt_point, settle, shots


def implant_colour(window: MainWindow) -> str:
    """The current implant's outline colour: red when its plan has a problem (issue 25)."""
    view = window.view
    return VIOLATED_COLOUR if view is not None and view.problems else IMPLANT_COLOUR


pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def _click(qtbot: QtBot, canvas: SliceCanvas, uv: np.ndarray, button: object = None) -> None:
    btn = Qt.MouseButton.LeftButton if button is None else button
    qtbot.mouseClick(canvas, btn, pos=qt_point(canvas, uv))  # type: ignore[arg-type]


def test_the_arch_is_placed_dragged_and_removed_on_the_axial_slice(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    window.resize(1440, 900)
    open_case(qtbot, window, phantom_case)
    settle(qtbot, window)
    doc, grid = window.doc, window.slice_grid
    ax = window.slice_canvases["axial"]
    assert ax.image is not None
    assert doc.set_arch(None)
    grid.toolbar.tool_buttons["arch"].click()
    assert ax.mode == "arch"
    left, right, bottom, top = ax.image.extent_mm
    w, h = right - left, bottom - top

    def at(fu: float, fv: float) -> np.ndarray:
        return np.array([left + fu * w, top + fv * h])

    z = grid.positions["axial"]
    _click(qtbot, ax, at(0.2, 0.3))
    assert doc.arch_lps is None and grid.arch_draft is not None and len(grid.arch_draft) == 1
    _click(qtbot, ax, at(0.8, 0.3))
    arch = doc.arch_lps
    assert arch is not None and arch.shape == (2, 3) and grid.arch_draft is None
    np.testing.assert_allclose(arch[:, 2], z, atol=1e-9)  # on the shown axial slice
    # a click on the segment inserts a vertex there
    mid = at(0.5, 0.3)
    _click(qtbot, ax, mid)
    arch = doc.arch_lps
    assert arch is not None and arch.shape == (3, 3)
    np.testing.assert_allclose(arch[1, :2], ax.image.to_lps(mid)[:2], atol=ax.image.pixel_mm)
    # drag the last vertex down
    start, end = qt_point(ax, at(0.8, 0.3)), qt_point(ax, at(0.8, 0.6))
    qtbot.mousePress(ax, Qt.MouseButton.LeftButton, pos=start)
    qtbot.mouseMove(ax, start + QPoint(0, 5))
    qtbot.mouseMove(ax, end)
    qtbot.mouseRelease(ax, Qt.MouseButton.LeftButton, pos=end)
    arch = doc.arch_lps
    assert arch is not None and arch.shape == (3, 3)
    uv, off = ax.image.to_plane_mm(arch[2])
    assert abs(float(off)) < 1e-9
    np.testing.assert_allclose(uv, at(0.8, 0.6), atol=1.5 * ax.image.pixel_mm)
    settle(qtbot, window)
    window.grab().save(str(shots(tmp_path) / "demo_arch.png"))
    # a right click on the first vertex removes it; undo brings it back
    _click(qtbot, ax, at(0.2, 0.3), Qt.MouseButton.RightButton)
    arch = doc.arch_lps
    assert arch is not None and arch.shape == (2, 3)
    assert doc.undo()
    arch = doc.arch_lps
    assert arch is not None and arch.shape == (3, 3)
    # Delete over a vertex removes it
    qtbot.mouseMove(ax, qt_point(ax, mid))
    qtbot.keyClick(ax, Qt.Key.Key_Delete)
    arch = doc.arch_lps
    assert arch is not None and arch.shape == (2, 3)
    # a point added after paging lies on the new slice
    qtbot.keyClick(ax, Qt.Key.Key_PageUp)
    settle(qtbot, window)
    z_up = grid.positions["axial"]
    assert z_up > z
    _click(qtbot, ax, at(0.5, 0.8))
    arch = doc.arch_lps
    assert arch is not None and arch.shape == (3, 3) and arch[2, 2] == pytest.approx(z_up)


def test_the_implant_body_is_drawn_to_its_profile(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    from dataclasses import replace

    window.resize(1440, 900)
    open_case(qtbot, window, phantom_case)
    doc = window.doc
    plan = window.plan
    assert plan is not None
    spec = next(s for s in load_implant_library() if s.apex == "round")
    with_implant = replace(plan, implant=spec)
    assert doc.set_plan(with_implant)
    settle(qtbot, window)
    placement = implant_placement(with_implant)
    assert placement is not None
    traj = window.slice_canvases["trajectory"]
    img = traj.image
    assert img is not None
    outlines = [
        np.asarray(p.get_xy())
        for p in traj.ax.patches
        if np.allclose(p.get_edgecolor()[:3], _rgb(implant_colour(window)))
    ]
    assert len(outlines) == 1
    pts = img.to_lps(outlines[0])
    rel = pts - placement.platform_lps
    s = rel @ placement.axis_lps
    rho = np.linalg.norm(rel - s[:, None] * placement.axis_lps, axis=1)
    s_k, r_k = spec.profile_mm()
    # the plane holds the axis: every outline vertex sits at the profile's radius
    np.testing.assert_allclose(rho, np.interp(s, s_k, r_k), atol=1e-9)
    assert (s.min(), s.max()) == pytest.approx((0.0, spec.length_mm), abs=1e-9)
    assert rho.max() == pytest.approx(spec.diameter_mm / 2.0, abs=1e-9)
    window.grab().save(str(shots(tmp_path) / "demo_implant.png"))


def test_the_arch_and_the_implant_of_a_real_ct_plan_on_the_slices(
    qtbot: QtBot, window: MainWindow, shared_data: Path, tmp_path: Path
) -> None:
    window.resize(1440, 900)
    plan_file = Path(__file__).resolve().parents[2] / "data" / "philips_head_arch.plan.json"
    window.open_plan(plan_file)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(shared_data / "dcmqa_ct_Philips_phantom_notilt_5mm")
    settle(qtbot, window)
    doc, grid = window.doc, window.slice_grid
    arch = doc.arch_lps
    assert arch is not None and window.plan is not None and window.plan.implant is not None
    ax = window.slice_canvases["axial"]
    # opened through the target (z 701.0 mm, between slices 1 and 2): one page up is the
    # arch's slice (z 701.21 mm, slice 2 of 28)
    assert ax.position_text().endswith("between slices 1 and 2")
    qtbot.keyClick(ax, Qt.Key.Key_PageUp)
    settle(qtbot, window)
    assert grid.positions["axial"] == pytest.approx(float(arch[0, 2]))
    assert ax.position_text().endswith("slice 2/28")
    assert ax.image is not None
    uv, off = ax.image.to_plane_mm(arch)
    np.testing.assert_allclose(off, 0.0, atol=1e-9)  # the arch lies on this slice
    solid = [
        ln for ln in ax.ax.lines if ln.get_linestyle() == "-" and len(ln.get_xdata()) == len(arch)
    ]
    assert any(np.allclose(np.asarray(ln.get_xydata()), uv) for ln in solid)
    qtbot.keyClick(ax, Qt.Key.Key_C)  # back to the drill: the implant is drawn on the planes
    settle(qtbot, window)
    implants = [
        p
        for c in window.slice_canvases.values()
        for p in c.ax.patches
        if np.allclose(p.get_edgecolor()[:3], _rgb(implant_colour(window)))
    ]
    assert implants
    window.grab().save(str(shots(tmp_path) / "philips_arch_implant.png"))
