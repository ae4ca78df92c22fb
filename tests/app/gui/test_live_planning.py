"""Planning at the speed of a drag, driven from outside as a script would (issue 27): the window
opened by ``open_window``, its views found by object name, real Qt mouse events, pixels mapped
to LPS by the views themselves.

- the target dragged on ``view:drill`` in 20 steps: ``plot:force``'s ``stopDepthMm`` follows
  every step (the stop the headless pipeline gives the plan under the mouse), one undo step;
- a click on a slice links the views there; a new trajectory zooms the slices to its site;
- a canal traced on ``view:panorama`` is saved with the LPS of the pixels clicked (the
  reformat's own pixel -> LPS map), an angle is measured on the cross-section and the implant
  slid along its axis there, its readout following.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QSettings, Qt
from PySide6.QtWidgets import QWidget
from pytestqt.qtbot import QtBot
from scipy.ndimage import map_coordinates

from ctdrill.api import open_window
from ctdrill.app.gui import slice_grid
from ctdrill.app.gui.implant_drag import dragged_plan, site_lps
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.map_ghost import GRIP_RADIUS_PX
from ctdrill.app.gui.plots import stop_title
from ctdrill.app.gui.readouts import implant_readout
from ctdrill.app.gui.results import compute_path_view
from ctdrill.app.gui.screenshot import qimage_to_rgb
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.load import load_plan_set
from ctdrill.imaging.sampling.arch import ArchCurve
from tests.app.gui.helpers import LOAD_TIMEOUT_MS

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

ROOT = Path(__file__).resolve().parents[3]
DEMO_CT = ROOT / "assets" / "demo" / "ct"
DEMO_PLAN = ROOT / "assets" / "demo" / "plan.json"


@pytest.fixture
def demo(qtbot: QtBot, tmp_path: Path) -> Iterator[MainWindow]:
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    win = open_window(DEMO_CT, [DEMO_PLAN], settings=settings)
    qtbot.addWidget(win)
    yield win
    win.close()
    assert win.internal_error == "", win.internal_error


def view(win: MainWindow, name: str) -> QWidget:
    found = win.findChild(QWidget, name)
    assert found is not None, name
    return found


def at(point: tuple[float, float]) -> QPoint:
    return QPoint(round(point[0]), round(point[1]))


def test_drag_on_the_drill_view_and_the_stop_follows_each_step(
    qtbot: QtBot, demo: MainWindow
) -> None:
    drill, plot = view(demo, "view:drill"), view(demo, "plot:force")
    plan = demo.doc.plan
    assert plan is not None and demo.doc.volume is not None
    assert plot.property("stopDepthMm") == pytest.approx(demo.view.curves.stop_depth_mm)
    start = drill.lps_to_pixel(plan.target_lps)  # type: ignore[attr-defined]
    assert start is not None
    x, y = start
    grabbed = drill.pixel_to_lps(*at(start).toTuple())  # type: ignore[attr-defined]
    qtbot.mousePress(drill, Qt.MouseButton.LeftButton, pos=at(start))
    followed = []
    violations = 0
    for k in range(1, 21):  # 20 steps, 3 px each down the drill: the implant moves deeper
        pos = at((x, y + 3 * k))
        with qtbot.waitSignal(plot.stopDepthMmChanged, timeout=LOAD_TIMEOUT_MS):
            qtbot.mouseMove(drill, pos)
        qtbot.waitUntil(lambda: demo.doc.live.path is not None, timeout=LOAD_TIMEOUT_MS)
        here = drill.pixel_to_lps(pos.x(), pos.y())  # type: ignore[attr-defined]
        expected_plan = dragged_plan(
            plan, "move", plan.target_lps, plan.target_lps + here - grabbed
        )
        shown = demo.doc.live.plan
        assert shown is not None
        np.testing.assert_allclose(shown.target_lps, expected_plan.target_lps, atol=1e-9)
        expected = compute_path_view(demo.doc.volume, expected_plan).curves.stop_depth_mm
        qtbot.waitUntil(
            lambda e=expected: abs(plot.property("stopDepthMm") - e) < 1e-9,
            timeout=LOAD_TIMEOUT_MS,
        )
        followed.append(plot.property("stopDepthMm"))
        # the status bar says the dragged plan's stop, as the plot does (not the plan's own)
        assert demo.statusBar().currentMessage() == stop_title(plot.curves)  # type: ignore[attr-defined]
        assert f"stop at {expected:.2f} mm" in demo.statusBar().currentMessage()
        banner = demo.views["banner"]
        if banner.kind == "violation":  # type: ignore[attr-defined]
            assert f"The drill stops at {expected:.2f} mm" in banner.text()  # type: ignore[attr-defined]
            violations += 1
    assert followed[-1] < followed[0]  # deeper toward the canal: the margin stops it sooner
    assert violations > 0  # the banner's stop is the plot's
    assert plot.blits > 0  # the curves were redrawn over the kept axes
    with qtbot.waitSignal(demo.path_updated, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseRelease(drill, Qt.MouseButton.LeftButton, pos=at((x, y + 60)))
    assert demo.doc.plan is not None and demo.doc.plan is not plan
    assert demo.undo_action.text() == "Undo move implant"
    demo.undo_action.trigger()
    assert demo.doc.plan is plan  # the whole drag was one step


def test_a_click_links_the_views_and_a_new_implant_zooms_to_its_site(
    qtbot: QtBot, demo: MainWindow, monkeypatch: pytest.MonkeyPatch
) -> None:
    fov = 20.0  # the demo is 32 x 40 x 32 mm: the site's 40 mm would be the whole image
    monkeypatch.setattr(slice_grid, "SITE_FOV_MM", fov)
    axial = view(demo, "view:axial")
    grid = demo.slice_grid
    spot = axial.pixel_to_lps(axial.width() * 0.3, axial.height() * 0.6)  # type: ignore[attr-defined]
    assert spot is not None
    with qtbot.waitSignal(grid.slices_updated, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseClick(axial, Qt.MouseButton.LeftButton, pos=at(axial.lps_to_pixel(spot)))  # type: ignore[attr-defined]
    linked = demo.doc.live.crosshair_lps
    assert linked is not None and np.allclose(linked, spot, atol=0.5)
    for name in ("coronal", "sagittal"):
        image = grid.slices[name]
        assert abs(float(image.to_plane_mm(linked)[1])) < 1e-6  # the plane through the point
        assert view(demo, f"view:{name}").lps_to_pixel(linked) is not None  # type: ignore[attr-defined]
    demo.plan_panel.trajectories.add.click()
    new = demo.doc.plan
    assert new is not None and new.name == "implant 1"  # the demo's own is named by its file
    qtbot.waitUntil(
        lambda: not grid.runner.busy and demo.ui_steps.pending == 0, timeout=LOAD_TIMEOUT_MS
    )
    site = site_lps(new)
    for name in ("view:axial", "view:coronal", "view:sagittal", "view:drill"):
        canvas = view(demo, name)
        x0, x1 = canvas.ax.get_xlim()  # type: ignore[attr-defined]
        y1, y0 = canvas.ax.get_ylim()  # type: ignore[attr-defined]
        assert x1 - x0 == pytest.approx(fov) and y1 - y0 == pytest.approx(fov)
        uv, _ = canvas.image.to_plane_mm(site)  # type: ignore[attr-defined]
        np.testing.assert_allclose(uv, [(x0 + x1) / 2, (y0 + y1) / 2], atol=1e-9)


def test_a_canal_traced_on_the_panorama_is_saved_where_the_pixels_were(
    qtbot: QtBot, demo: MainWindow, tmp_path: Path
) -> None:
    page = demo.views["panorama"]
    with qtbot.waitSignals([page.drawn, page.drawn], timeout=LOAD_TIMEOUT_MS):  # type: ignore[attr-defined]
        demo.pages.setCurrentWidget(page)
    qtbot.waitUntil(lambda: demo.ui_steps.pending == 0, timeout=LOAD_TIMEOUT_MS)
    pano = view(demo, "view:panorama")
    reformat = page.pano_image  # type: ignore[attr-defined]
    assert reformat is not None
    page.tools.buttons["canal"].click()  # type: ignore[attr-defined]
    page.tools.choice.canal.setCurrentText("traced on the panorama")  # type: ignore[attr-defined]
    page.tools.choice._canal_chosen()  # type: ignore[attr-defined]
    # three clicks in the middle of arch segments, at mid height: widget pixels
    curve = ArchCurve(reformat.arch_lps)
    bounds = np.concatenate(
        [[0.0], np.cumsum(np.linalg.norm(np.diff(reformat.arch_lps[:, :2], axis=0), axis=1))]
    )
    h, _w = reformat.shape
    clicks = []
    for k in (3, 8, 14):
        u = 0.5 * (bounds[k] + bounds[k + 1])
        lps = reformat.lps_at(np.array([u, 0.45 * (h - 1) * reformat.pixel_mm]))
        clicks.append(at(pano.lps_to_pixel(lps)))  # type: ignore[attr-defined]
    for pos in clicks:
        with qtbot.waitSignal(demo.doc.plans_changed, timeout=LOAD_TIMEOUT_MS):
            qtbot.mouseClick(pano, Qt.MouseButton.LeftButton, pos=pos)
    out = tmp_path / "traced.json"
    demo.save_plan(out)
    (saved,) = [
        lm for lm in load_plan_set([out])[0].landmarks if lm.name == "traced on the panorama"
    ]
    assert isinstance(saved, CanalLandmark) and len(saved.points_lps) == 3
    # the reformat's own map: each pixel centre's LPS, linear between them (a column pair on
    # one arch segment, rows at fixed heights) -> where the widget pixel falls
    ratio = pano.devicePixelRatioF()
    for pos in clicks:
        uv = pano.ax.transData.inverted().transform(
            (pos.x() * ratio, (pano.height() - pos.y()) * ratio)
        )  # type: ignore[attr-defined]
        ij = np.array([[uv[1] / reformat.pixel_mm], [uv[0] / reformat.pixel_mm]])
        seg = int(np.searchsorted(bounds, uv[0]) - 1)
        assert bounds[seg] <= np.floor(ij[1, 0]) * reformat.pixel_mm
        assert np.ceil(ij[1, 0]) * reformat.pixel_mm <= bounds[seg + 1]
        expected = [map_coordinates(reformat.lps[..., c], ij, order=1)[0] for c in range(3)]
        found = saved.points_lps[np.argmin(np.linalg.norm(saved.points_lps - expected, axis=1))]
        np.testing.assert_allclose(found, expected, atol=1e-6)
    assert curve.length_mm > 0
    assert demo.undo_action.text() == "Undo trace 'traced on the panorama'"

    # the cross-section: an angle of three clicks, then the implant slid along its axis
    cross = view(demo, "view:cross_section")
    page.tools.buttons["angle"].click()  # type: ignore[attr-defined]
    cw, ch = cross.width(), cross.height()
    for fx, fy in ((0.3, 0.3), (0.5, 0.5), (0.7, 0.3)):
        qtbot.mouseClick(
            cross, Qt.MouseButton.LeftButton, pos=QPoint(round(cw * fx), round(ch * fy))
        )
    assert cross.tools.label is not None and cross.tools.label.endswith("°")  # type: ignore[attr-defined]
    page.tools.buttons["navigate"].click()  # type: ignore[attr-defined]
    plan = demo.doc.plan
    qtbot.waitUntil(
        lambda: demo.doc.live.readout is not None and demo.ui_steps.pending == 0,
        timeout=LOAD_TIMEOUT_MS,
    )
    assert plan is not None and demo.doc.live._readout_for is plan
    before = page.readout.text()  # type: ignore[attr-defined]
    assert "implant body" in before and "thinnest wall" in before
    assert "below the crest" in before or "above the crest" in before
    body = cross.lps_to_pixel(0.5 * (plan.target_lps + plan.entry_lps))  # type: ignore[attr-defined]
    assert body is not None
    mods = Qt.KeyboardModifier.ShiftModifier
    qtbot.mousePress(cross, Qt.MouseButton.LeftButton, mods, at(body))
    with qtbot.waitSignal(demo.doc.live.path_changed, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseMove(cross, at((body[0], body[1] + 12)))
    qtbot.waitUntil(lambda: page.readout.text() != before, timeout=LOAD_TIMEOUT_MS)  # type: ignore[attr-defined]
    with qtbot.waitSignal(demo.path_updated, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseRelease(cross, Qt.MouseButton.LeftButton, mods, at((body[0], body[1] + 12)))
    slid = demo.doc.plan
    assert slid is not None and np.array_equal(slid.entry_lps, plan.entry_lps)
    assert slid.planned_depth_mm > plan.planned_depth_mm  # down the image: deeper
    assert demo.undo_action.text() == "Undo slide implant along its axis"


def ghost_is_painted_at_its_grips(canvas: QWidget) -> None:
    """The ghost's grips are rings painted over the image (the pixels a ghost-less paint
    shows differ on each ring), and the ghost changes nothing outside the axes."""
    ghost = canvas.ghost_uv  # type: ignore[attr-defined]
    assert ghost is not None and ghost[1].shape[0] >= 1
    with_ghost = qimage_to_rgb(canvas.grab().toImage())
    canvas.end_ghost()  # type: ignore[attr-defined]
    without = qimage_to_rgb(canvas.grab().toImage())
    changed = np.any(with_ghost != without, axis=-1)
    ratio = canvas.devicePixelRatioF()
    xy = canvas.ax.transData.transform(ghost[1]) / ratio  # type: ignore[attr-defined]
    h = canvas.height()
    for gx, gy in zip(xy[:, 0], h - xy[:, 1], strict=True):
        ring = [(gx + GRIP_RADIUS_PX * np.cos(a), gy + GRIP_RADIUS_PX * np.sin(a)) for a in
                np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False)]  # fmt: skip
        hits = [changed[int(v) - 1 : int(v) + 2, int(u) - 1 : int(u) + 2].any() for u, v in ring]
        assert sum(hits) >= 6, (gx, gy, hits)
    x0, y0, x1, y1 = canvas.ax.bbox.extents / ratio  # type: ignore[attr-defined]
    outside = changed.copy()
    outside[int(h - y1) : int(h - y0) + 1, int(x0) : int(x1) + 1] = False
    assert not outside.any()


def test_a_fast_drag_is_coalesced_to_its_latest_position_once_per_pass(
    qtbot: QtBot, demo: MainWindow
) -> None:
    """Moves delivered in one burst report one plan (the last position's), its ghost computed
    once by the paint; the plots draw the latest result once at their paint."""
    drill, plot = view(demo, "view:drill"), view(demo, "plot:force")
    plan = demo.doc.plan
    assert plan is not None
    x, y = drill.lps_to_pixel(plan.target_lps)  # type: ignore[attr-defined]
    reported: list[object] = []
    drill.grip_dragged.connect(lambda *args: reported.append(args))  # type: ignore[attr-defined]
    ghosts: list[object] = []
    draw_ghost = drill.draw_ghost_of  # type: ignore[attr-defined]
    drill.draw_ghost_of = lambda p: (ghosts.append(p), draw_ghost(p))  # type: ignore[attr-defined]
    qtbot.mousePress(drill, Qt.MouseButton.LeftButton, pos=at((x, y)))
    qtbot.waitUntil(lambda: demo.doc.live.path is not None, timeout=LOAD_TIMEOUT_MS)
    qtbot.waitUntil(lambda: len(ghosts) > 0, timeout=LOAD_TIMEOUT_MS)  # the press's preview
    reported.clear()
    ghosts.clear()
    for k in range(1, 6):  # five moves before the event loop runs
        qtbot.mouseMove(drill, at((x, y + 3 * k)))
    assert reported == []  # nothing reported yet: the latest waits for the next pass
    with qtbot.waitSignal(plot.stopDepthMmChanged, timeout=LOAD_TIMEOUT_MS):
        qtbot.waitUntil(lambda: len(reported) > 0, timeout=LOAD_TIMEOUT_MS)
    assert len(reported) == 1
    here = drill.pixel_to_lps(x, y + 15)  # type: ignore[attr-defined]
    grabbed = drill.pixel_to_lps(x, y)  # type: ignore[attr-defined]
    dragged = demo.doc.live.plan
    assert dragged is not None
    np.testing.assert_allclose(dragged.target_lps, plan.target_lps + here - grabbed, atol=1e-9)
    qtbot.waitUntil(lambda: len(ghosts) > 0, timeout=LOAD_TIMEOUT_MS)
    assert (
        len(ghosts) == 1 and ghosts[0] is dragged
    )  # one ghost, the latest plan's, drawn by the paint
    qtbot.waitUntil(
        lambda: demo.doc.live.path is not None and demo.doc.live.path.plan is dragged,
        timeout=LOAD_TIMEOUT_MS,
    )
    qtbot.waitUntil(lambda: plot.curves is demo.doc.live.path.curves, timeout=LOAD_TIMEOUT_MS)  # type: ignore[attr-defined,union-attr]
    ghost_is_painted_at_its_grips(drill)
    # the cross-section's readout follows the drag: the dragged position's, before the release
    assert demo.doc.volume is not None
    expected = implant_readout(demo.doc.volume, dragged, demo.doc.live.path)
    qtbot.waitUntil(lambda: demo.doc.live.readout == expected, timeout=LOAD_TIMEOUT_MS)
    with qtbot.waitSignal(demo.path_updated, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseRelease(drill, Qt.MouseButton.LeftButton, pos=at((x, y + 15)))
    assert demo.doc.plan is dragged
