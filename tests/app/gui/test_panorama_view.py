"""The panorama and cross-section page, driven as a user would, on the demo and a real head."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication
from pytestqt.qtbot import QtBot

from ctdrill.app.gui import reformats
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.panorama_view import PanoramaView, ReformatCanvas
from ctdrill.app.gui.screenshot import qimage_to_rgb, region_stats, widget_rect
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.reformat import arc_position_mm
from tests.app.gui.helpers import LOAD_TIMEOUT_MS

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

ROOT = Path(__file__).resolve().parents[3]
DEMO_CT = ROOT / "assets" / "demo" / "ct"
DEMO_PLAN = ROOT / "assets" / "demo" / "plan.json"
PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"
PHILIPS_PLAN = ROOT / "tests" / "data" / "philips_head_arch.plan.json"


def open_page(qtbot: QtBot, window: MainWindow, ct: Path, plan: Path) -> PanoramaView:
    """Open ``plan`` and ``ct``, show the panorama page, wait until both images are drawn."""
    assert window.open_plan(plan)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(ct)
    view: PanoramaView = window.views["panorama"]  # type: ignore[assignment]
    assert view.pano_image is None  # nothing computed while the page was hidden
    with qtbot.waitSignals([view.drawn, view.drawn], timeout=LOAD_TIMEOUT_MS):
        window.pages.setCurrentWidget(view)
    settle(qtbot, window, view)
    return view


def settle(qtbot: QtBot, window: MainWindow, view: PanoramaView) -> None:
    """Wait until no reformat is computing and every drawing step ran."""
    qtbot.waitUntil(
        lambda: (
            not view.pano_runner.busy
            and not view.cross_runner.busy
            and window.ui_steps.pending == 0
        ),
        timeout=LOAD_TIMEOUT_MS,
    )


def wheel(canvas: ReformatCanvas, notches: int, shift: bool = False) -> None:
    pos = QPointF(canvas.width() / 2, canvas.height() / 2)
    mods = Qt.KeyboardModifier.ShiftModifier if shift else Qt.KeyboardModifier.NoModifier
    event = QWheelEvent(
        pos,
        canvas.mapToGlobal(pos),
        QPoint(0, 0),
        QPoint(0, 120 * notches),
        Qt.MouseButton.NoButton,
        mods,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    QApplication.sendEvent(canvas, event)


def at_mm(qtbot: QtBot, window: MainWindow, view: PanoramaView) -> float:
    settle(qtbot, window, view)
    assert view.cross_image is not None and view.cross_image.at_arc_mm is not None
    return view.cross_image.at_arc_mm


def click_panorama(qtbot: QtBot, view: PanoramaView, x_mm: float) -> None:
    """A left click on the panorama at column ``x_mm`` (mid height)."""
    canvas, ax = view.pano, view.pano.ax
    y_mm = float(np.mean(ax.get_ylim()))
    x_px, y_px = ax.transData.transform((x_mm, y_mm))
    ratio = canvas.devicePixelRatioF()
    point = QPoint(round(x_px / ratio), round(canvas.height() - y_px / ratio))
    qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=point)


def cross_centre_lps(view: PanoramaView) -> np.ndarray:
    image = view.cross_image
    assert image is not None
    h, w = image.shape
    return np.asarray(image.lps[h // 2, w // 2])


def test_demo_cross_section_scrolls_along_the_arch_and_follows_the_panorama(
    qtbot: QtBot, window: MainWindow, tmp_path: Path
) -> None:
    view = open_page(qtbot, window, DEMO_CT, DEMO_PLAN)
    plan, volume = window.plan, window.volume
    assert plan is not None and plan.arch_lps is not None and volume is not None
    length = reformats.arch_length_mm(plan.arch_lps)
    # It starts at the implant's site, its plane containing the axis (centred on its middle).
    mid = 0.5 * (plan.entry_lps + plan.target_lps)
    site = at_mm(qtbot, window, view)
    assert site == pytest.approx(arc_position_mm(plan.arch_lps, mid), abs=1e-6)
    np.testing.assert_allclose(cross_centre_lps(view), mid, atol=1e-9)
    assert view.position.text() == f"{site:.1f} mm of {length:.1f} mm along the arch " + (
        "(the implant's site)"
    )
    shot = tmp_path / "demo_panorama.png"
    window.save_screenshot(shot)
    img = qimage_to_rgb(window.grab_composite())
    for canvas in (view.pano, view.cross):
        r = widget_rect(canvas, window)
        assert region_stats(img, (r.x(), r.y(), r.width(), r.height())).drawn

    wheel(view.cross, 1)  # one notch: 1 mm along the arch, the same tilt
    assert at_mm(qtbot, window, view) == pytest.approx(site + reformats.STEP_MM)
    wheel(view.cross, -1, shift=True)
    assert at_mm(qtbot, window, view) == pytest.approx(site + 1.0 - reformats.BIG_STEP_MM)
    view.cross.setFocus()
    qtbot.keyClick(view.cross, Qt.Key.Key_PageUp)
    qtbot.keyClick(view.cross, Qt.Key.Key_Down)
    assert at_mm(qtbot, window, view) == pytest.approx(site + 1.0 - 5.0 + 5.0 - 1.0)
    assert "(the implant's site)" not in view.position.text()
    for _ in range(3):  # held against the arch's end: it stops there
        wheel(view.cross, 10, shift=True)
        settle(qtbot, window, view)
    assert at_mm(qtbot, window, view) == pytest.approx(length)

    click_panorama(qtbot, view, 10.0)  # the cross-section jumps to the clicked column
    ax = view.pano.ax
    lo, hi = ax.get_xlim()
    mm_per_px = (hi - lo) / ax.bbox.width * view.pano.devicePixelRatioF()
    assert at_mm(qtbot, window, view) == pytest.approx(10.0, abs=mm_per_px)
    view.to_implant.click()
    assert at_mm(qtbot, window, view) == pytest.approx(site, abs=1e-6)

    # Slab controls: one plane (0 mm) samples the CT exactly at each pixel; MIP is kept.
    view.cross_controls.slab.setValue(0.0)
    assert view.cross_controls.busy.text() == "computing ..."
    assert view.pano_controls.busy.text() == ""  # the panorama did not change
    settle(qtbot, window, view)
    assert view.cross_controls.busy.text() == ""
    image = view.cross_image
    assert image is not None and image.slab_mm == 0.0
    np.testing.assert_allclose(image.hu, volume.sample(image.lps, outside_hu=-1000.0), atol=1e-9)
    view.pano_controls.mode.setCurrentIndex(1)
    view.pano_controls.slab.setValue(4.0)
    settle(qtbot, window, view)
    assert view.pano_image is not None
    assert (view.pano_image.slab_mode, view.pano_image.slab_mm) == ("mip", 4.0)


def test_another_trajectory_puts_the_cross_section_on_its_implant(
    qtbot: QtBot, window: MainWindow
) -> None:
    view = open_page(qtbot, window, DEMO_CT, DEMO_PLAN)
    first = window.plan
    assert first is not None and first.arch_lps is not None
    site = at_mm(qtbot, window, view)
    window.plan_panel.trajectories.add.click()  # 8 mm along the arch
    second = window.plan
    assert second is not None and second is not first
    moved = at_mm(qtbot, window, view)
    assert abs(moved - site) == pytest.approx(8.0, abs=0.5)  # the arch curves: nearly 8 mm
    mid = 0.5 * (second.entry_lps + second.target_lps)
    np.testing.assert_allclose(cross_centre_lps(view), mid, atol=1e-9)
    window.plan_panel.trajectories.list.setCurrentRow(0)
    assert at_mm(qtbot, window, view) == pytest.approx(site, abs=1e-6)


def test_without_an_arch_the_page_says_how_to_draw_one_and_undo_removes_it(
    qtbot: QtBot, window: MainWindow, tmp_path: Path
) -> None:
    from ctdrill.imaging.plan.load import load_plan_set
    from ctdrill.imaging.plan.write import write_plans

    demo = load_plan_set([DEMO_PLAN])[0]
    arch = demo.arch_lps
    assert arch is not None
    no_arch = tmp_path / "no_arch.json"
    write_plans([replace(demo, arch_lps=None)], no_arch)
    assert window.open_plan(no_arch)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(DEMO_CT)
    view: PanoramaView = window.views["panorama"]  # type: ignore[assignment]
    window.pages.setCurrentWidget(view)
    assert view.pano.message == reformats.NO_ARCH and "Arch tool" in view.pano.message
    shot = tmp_path / "no_arch.png"
    window.save_screenshot(shot)
    with qtbot.waitSignals([view.drawn, view.drawn], timeout=LOAD_TIMEOUT_MS):
        assert window.doc.set_arch(arch)  # as the axial view's arch tool does
    assert window.undo_action.text() == "Undo draw arch"
    window.undo_action.trigger()
    assert window.plan is not None and window.plan.arch_lps is None
    assert view.pano.message == reformats.NO_ARCH and view.pano_image is None
    window.redo_action.trigger()
    settle(qtbot, window, view)
    assert view.pano_image is not None and np.array_equal(view.pano_image.arch_lps, arch)


def test_real_head_panorama_and_cross_section_through_the_implant(
    qtbot: QtBot, window: MainWindow, shared_data: Path, tmp_path: Path
) -> None:
    view = open_page(qtbot, window, shared_data / PHILIPS, PHILIPS_PLAN)
    plan = window.plan
    assert isinstance(plan, Plan) and plan.arch_lps is not None
    mid = 0.5 * (plan.entry_lps + plan.target_lps)
    np.testing.assert_allclose(cross_centre_lps(view), mid, atol=1e-9)
    pano = view.pano_image
    assert pano is not None and window.volume is not None
    # The panorama spans the arch's length and the head's whole height.
    length = reformats.arch_length_mm(plan.arch_lps)
    assert pano.extent_mm[0] == pytest.approx(length, abs=pano.pixel_mm)
    assert float(pano.lps[0, 0, 2]) > float(pano.lps[-1, 0, 2])  # rows run down, upright
    img = qimage_to_rgb(window.grab_composite())
    for canvas in (view.pano, view.cross):
        r = widget_rect(canvas, window)
        assert region_stats(img, (r.x(), r.y(), r.width(), r.height())).drawn
    window.save_screenshot(tmp_path / "philips_panorama.png")
    wheel(view.cross, -3)
    site = arc_position_mm(plan.arch_lps, mid)
    assert at_mm(qtbot, window, view) == pytest.approx(site - 3.0)
    # A second implant on the real head: added along the arch, the cross-section follows it;
    # undone, the cross-section is back on the first implant.
    window.plan_panel.trajectories.add.click()
    assert len(window.doc.plans) == 2
    assert at_mm(qtbot, window, view) == pytest.approx(site + 8.0, abs=0.5)
    window.undo_action.trigger()
    assert len(window.doc.plans) == 1 and window.plan is plan
    assert at_mm(qtbot, window, view) == pytest.approx(site, abs=1e-6)
    window.save_screenshot(tmp_path / "philips_after_undo.png")
