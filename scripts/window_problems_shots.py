"""Screenshots of the window saying what the outputs say (issue 25): the banner listing every
plan problem, the landmark table's planned clearances, the offending implant drawn red, and a
coarse series named.

Run under a display (Xvfb), from the repository root::

    xvfb-run -a -s "-screen 0 1600x1000x24" env QT_QPA_PLATFORM=xcb \\
        .venv/bin/python scripts/window_problems_shots.py OUT_DIR

Writes ``demo_plan.png`` and ``demo_panorama.png`` (the demo CT with the issue's case: entry
(36.1, 10, -30.5), target (36.1, 10, -42.5), implant ``parallel 4.1 x 11.5``,
``bone-literature``) and ``head_plan.png`` and ``head_panorama.png`` (the real VTK head CT,
NIfTI at 3.2 mm voxels, with its arch plan, a ``tapered 4.1 x 10`` implant and a test canal
below it), and prints each trajectory's problems.
"""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
from PySide6.QtCore import QEventLoop, QSettings, QTimer, SignalInstance
from PySide6.QtWidgets import QApplication

from ctdrill.app.gui.app import make_window
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging.plan.implants import load_implant_library
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.load import load_plan

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
TIMEOUT_MS = 120_000


def wait_signal(signal: SignalInstance, start: Callable[[], object]) -> None:
    """Run ``start`` and wait for ``signal`` (at most :data:`TIMEOUT_MS`)."""
    loop = QEventLoop()
    signal.connect(loop.quit)
    QTimer.singleShot(TIMEOUT_MS, loop.quit)
    start()
    loop.exec()
    signal.disconnect(loop.quit)


def wait_until(done: Callable[[], bool]) -> None:
    """Process events until ``done()`` (at most :data:`TIMEOUT_MS`)."""
    app = QApplication.instance()
    timer = QTimer()
    timer.start(TIMEOUT_MS)
    while not done() and timer.isActive():
        assert app is not None
        app.processEvents()


def settle(win: MainWindow) -> None:
    """Wait until every computation and drawing step of the window ran."""
    pano = win.views["panorama"]
    ctl = win.controller
    wait_until(
        lambda: (
            win.ui_steps.pending == 0
            and not ctl.path_runner.busy
            and not ctl.readout_runner.busy
            and not pano.pano_runner.busy  # type: ignore[attr-defined]
            and not pano.cross_runner.busy  # type: ignore[attr-defined]
        )
    )


def shoot(win: MainWindow, ct: Path, plan: object, out: Path, stem: str) -> None:
    """Open ``plan`` on ``ct``; save the main page with the Plan tab and the panorama page."""
    win.pages.setCurrentIndex(0)
    assert win.use_plans([plan])  # type: ignore[list-item]
    wait_signal(win.path_updated, lambda: win.open_folder(ct))
    win.tabs.setCurrentWidget(win.plan_panel)
    settle(win)
    win.save_screenshot(out / f"{stem}_plan.png")
    pano = win.views["panorama"]
    wait_signal(pano.drawn, lambda: win.pages.setCurrentWidget(pano))  # type: ignore[attr-defined]
    settle(win)
    win.save_screenshot(out / f"{stem}_panorama.png")
    view = win.view
    print(f"{stem}: {ct.name}")
    for w in () if view is None else view.problems:
        print(f"  {w.code}: {w.message}")
    banner = win.views["banner"]
    print(f"  banner ({banner.kind}): {banner.text()}")  # type: ignore[attr-defined]


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    app = QApplication.instance() or QApplication(sys.argv)
    lib = {spec.name: spec for spec in load_implant_library()}
    with tempfile.TemporaryDirectory() as tmp:
        win = make_window(QSettings(str(Path(tmp) / "s.ini"), QSettings.Format.IniFormat))
        win.unattended = True
        win.show()
        demo = replace(
            load_plan(ROOT / "assets" / "demo" / "plan.json"),
            entry_lps=np.array([36.1, 10.0, -30.5]),
            target_lps=np.array([36.1, 10.0, -42.5]),
            implant=lib["parallel 4.1 x 11.5"],
            calibration="bone-literature",
            name="issue 25 case",
        )
        shoot(win, ROOT / "assets" / "demo" / "ct", demo, out, "demo")
        head = load_plan(ROOT / "tests" / "data" / "headsq_quarter.plan.json")
        below = head.target_lps + np.array([0.0, 0.0, -3.0])
        test_canal = CanalLandmark(
            "test canal (not anatomy)",
            below + np.array([[-10.0, 5.0, 0.0], [10.0, -5.0, 0.0]]),
            radius_mm=1.2,
        )
        head = replace(head, implant=lib["tapered 4.1 x 10"], landmarks=(test_canal,))
        shoot(win, SHARED / "vtk_headsq_quarter" / "headsq_quarter.nii.gz", head, out, "head")
        win.close()
    assert app is not None


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "screenshots"))
