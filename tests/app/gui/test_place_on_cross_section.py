"""The first implant placed on the cross-section with real Qt events, and right-clicks that
either act or say why not (issue 34)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.panorama_view import PanoramaView, ReformatCanvas
from ctdrill.imaging.plan.load import load_plan
from tests.app.gui.helpers import LOAD_TIMEOUT_MS
from tests.app.gui.test_panorama_view import DEMO_CT, DEMO_PLAN, click_panorama, settle

pytestmark = pytest.mark.gui


def _px(canvas: ReformatCanvas, u_mm: float, v_mm: float) -> QPoint:
    x_px, y_px = canvas.ax.transData.transform((u_mm, v_mm))
    ratio = canvas.devicePixelRatioF()
    return QPoint(round(x_px / ratio), round(canvas.height() - y_px / ratio))


def test_the_first_implant_is_placed_on_the_cross_section(qtbot: QtBot, window: MainWindow) -> None:
    arch = load_plan(DEMO_PLAN).arch_lps
    with qtbot.waitSignal(window.doc.volume_changed, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(DEMO_CT)
    assert window.plan is None and arch is not None
    window.doc.set_arch(arch)
    view: PanoramaView = window.views["panorama"]  # type: ignore[assignment]
    window.pages.setCurrentWidget(view)
    settle(qtbot, window, view)
    assert view.pano_image is not None
    click_panorama(qtbot, view, float(np.mean(view.pano.ax.get_xlim())))
    qtbot.waitUntil(lambda: view.cross_image is not None, timeout=LOAD_TIMEOUT_MS)
    settle(qtbot, window, view)
    image = view.cross_image
    assert image is not None
    h, w = image.shape
    p = image.pixel_mm
    target_uv = (0.5 * (w - 1) * p, 0.6 * (h - 1) * p)
    entry_uv = (0.5 * (w - 1) * p, 0.3 * (h - 1) * p)
    canvas = view.cross
    qtbot.mouseClick(canvas, Qt.MouseButton.RightButton, pos=_px(canvas, *target_uv))
    assert window.plan is None and "now place the entry" in window.statusBar().currentMessage()
    qtbot.mouseClick(
        canvas,
        Qt.MouseButton.RightButton,
        Qt.KeyboardModifier.ShiftModifier,
        pos=_px(canvas, *entry_uv),
    )
    plan = window.plan
    assert plan is not None
    expect = image.lps[round(0.6 * (h - 1)), round(0.5 * (w - 1))]
    assert np.linalg.norm(plan.target_lps - expect) < 2 * p  # within two pixels of the click


def test_a_right_click_that_cannot_act_says_why(qtbot: QtBot, window: MainWindow) -> None:
    assert window.open_plan(DEMO_PLAN)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(DEMO_CT)
    view: PanoramaView = window.views["panorama"]  # type: ignore[assignment]
    with qtbot.waitSignals([view.drawn, view.drawn], timeout=LOAD_TIMEOUT_MS):
        window.pages.setCurrentWidget(view)
    settle(qtbot, window, view)
    view.set_mode("distance")
    centre = QPoint(view.pano.width() // 2, view.pano.height() // 2)
    qtbot.mouseClick(view.pano, Qt.MouseButton.RightButton, pos=centre)
    assert "none there" in window.statusBar().currentMessage()


def test_the_fdi_site_field_is_typed_and_validated(qtbot: QtBot, window: MainWindow) -> None:
    assert window.open_plan(DEMO_PLAN)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(DEMO_CT)
    field = window.plan_panel.site
    field.setFocus()
    field.selectAll()
    qtbot.keyClicks(field, "36")
    qtbot.keyClick(field, Qt.Key.Key_Return)
    assert window.plan is not None and window.plan.site == 36
    field.selectAll()
    qtbot.keyClicks(field, "99")
    qtbot.keyClick(field, Qt.Key.Key_Return)
    assert window.plan.site == 36  # refused, said why
    assert (
        "FDI" in window.statusBar().currentMessage()
        or "quadrant" in window.statusBar().currentMessage()
    )
    assert field.text() == "36"


def test_the_banner_keeps_its_height_and_scrolls(qtbot: QtBot, window: MainWindow) -> None:
    from ctdrill.app.gui.banner import BANNER_PX, Banner

    banner = window.views["banner"]
    assert isinstance(banner, Banner)
    text = "5 problems\n" + "\n".join(f"• problem {k}: " + "words " * 30 for k in range(5))
    banner.show_banner((text, "violation"))
    qtbot.waitUntil(banner.isVisible, timeout=LOAD_TIMEOUT_MS)
    assert banner.height() == BANNER_PX and banner.text() == text
    qtbot.waitUntil(lambda: banner.verticalScrollBar().maximum() > 0, timeout=LOAD_TIMEOUT_MS)


@pytest.mark.slow  # a whole report in the background: ~10 s idle (make fuzz runs it)
def test_file_report_writes_the_pdf_of_the_plan(
    qtbot: QtBot, window: MainWindow, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from PySide6.QtGui import QAction
    from PySide6.QtWidgets import QFileDialog

    assert window.open_plan(DEMO_PLAN)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(DEMO_CT)
    out = tmp_path / "case.pdf"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(out), "PDF"))
    (action,) = [a for a in window.findChildren(QAction) if a.text() == "Report..."]
    action.trigger()
    qtbot.waitUntil(lambda: "wrote" in window.statusBar().currentMessage(), timeout=120_000)
    assert out.read_bytes().startswith(b"%PDF-")
    assert f"wrote {out}" in window.statusBar().currentMessage()
