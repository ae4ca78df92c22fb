"""The teleoperation page on the demo: run the slave, see both depths, forces and CT numbers."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.screenshot import qimage_to_rgb, region_stats, widget_rect
from ctdrill.app.gui.teleop_view import TeleopView
from tests.app.gui.helpers import LOAD_TIMEOUT_MS

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

ROOT = Path(__file__).resolve().parents[3]
DEMO_CT = ROOT / "assets" / "demo" / "ct"
DEMO_PLAN = ROOT / "assets" / "demo" / "plan.json"


def test_the_slave_runs_from_the_window_and_its_figure_is_drawn(
    qtbot: QtBot, window: MainWindow, tmp_path: Path
) -> None:
    view: TeleopView = window.views["teleop"]  # type: ignore[assignment]
    assert not view.run()  # nothing loaded: it says so instead of running
    assert "Load a CT" in view.message.text()
    assert window.open_plan(DEMO_PLAN)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(DEMO_CT)
    window.pages.setCurrentWidget(view)
    view.duration.setValue(2.5)
    view.misregister.setValue(3.0)
    assert view.run()
    qtbot.waitUntil(lambda: view.result is not None, timeout=LOAD_TIMEOUT_MS)
    run, figures = view.result  # type: ignore[misc]
    assert run.stop_reason == figures["stop_reason"] == "cortex_exit"  # the canal 3 mm early
    assert "cortex_exit" in view.message.text()
    axes = view.figure.axes
    assert len(axes) == 3
    assert [len(ax.lines) for ax in axes] == [4, 2, 2]  # 3 depths and the stop, forces, HU
    assert np.nanmax(axes[2].lines[1].get_ydata()) > 1500.0  # the estimate saw the cortex
    qtbot.wait(50)
    image = window.grab().toImage()
    shot = os.environ.get("CTDRILL_TELEOP_SCREENSHOT")
    if shot:
        image.save(shot)
    rect = widget_rect(view.canvas, window)
    stats = region_stats(qimage_to_rgb(image), (rect.x(), rect.y(), rect.width(), rect.height()))
    assert stats.drawn  # the plot is drawn, not a blank canvas
