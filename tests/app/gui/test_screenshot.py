"""Screenshots really show the drawing: pixel statistics in the 3D area and the plot area."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtGui import QImage
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.app import window_size
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.screenshot import qimage_to_rgb, region_stats, widget_rect
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import open_case

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

ROOT = Path(__file__).resolve().parents[3]


def rect_tuple(widget: object, window: MainWindow) -> tuple[int, int, int, int]:
    r = widget_rect(widget, window)  # type: ignore[arg-type]
    return (r.x(), r.y(), r.width(), r.height())


def test_region_stats_tell_a_flat_fill_from_a_drawing() -> None:
    flat = np.full((50, 80, 3), 30, dtype=np.uint8)
    assert not region_stats(flat).drawn
    ramp = np.repeat(np.linspace(0, 255, 80, dtype=np.uint8)[None, :, None], 50, 0)
    ramp = np.repeat(ramp, 3, axis=2)
    stats = region_stats(ramp)
    assert stats.drawn and stats.levels == 80
    assert not region_stats(ramp, (0, 0, 1, 50)).drawn  # one column: a single grey


def test_window_size_prefers_1440x900_and_never_under_1280x800() -> None:
    assert window_size((1920, 1080)) == (1440, 900)
    assert window_size((1366, 768)) == (1366, 768)
    assert window_size((1280, 800)) == (1280, 800)
    assert window_size((1600, 1000)) == (1440, 900)


def test_composited_screenshot_shows_the_3d_view_and_the_plots(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    path = tmp_path / "window.png"
    window.save_screenshot(path)
    img = qimage_to_rgb(QImage(str(path)))
    assert img.shape[1] >= 1280 and img.shape[0] >= 800
    view3d = region_stats(img, rect_tuple(window.view3d, window))
    plots = region_stats(img, rect_tuple(window.plot_canvas, window))
    slices = region_stats(img, rect_tuple(window.slice_canvases["trajectory"], window))
    assert view3d.drawn and plots.drawn and slices.drawn
    assert view3d.mean > 20  # not a black GL area
    # The bone (beige), the canal (yellow) and the drill (grey) are in the 3D area, not only
    # the blue-grey background: count warm pixels (red well above blue).
    x, y, w, h = rect_tuple(window.view3d, window)
    area = img[y : y + h, x : x + w].astype(int)
    warm = (area[..., 0] - area[..., 2]) > 40
    assert warm.mean() > 0.05


def test_cli_screenshot_of_the_phantom(phantom_case: PhantomCase, tmp_path: Path) -> None:
    shot = tmp_path / "cli.png"
    env = {
        **os.environ,
        "QT_QPA_PLATFORM": os.environ.get("QT_QPA_PLATFORM", "xcb"),
        "XDG_CONFIG_HOME": str(tmp_path / "config"),  # the recent-folder list goes here
    }
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "ctdrill.app.cli",
            "gui",
            "--dicom",
            str(phantom_case.ct_dir),
            "--plan",
            str(phantom_case.plan_path),
            "--screenshot",
            str(shot),
            "--quit-after-s",
            "60",
        ],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "blank" not in proc.stderr
    recent = (tmp_path / "config" / "ctdrill" / "ctdrill.conf").read_text()
    assert str(phantom_case.ct_dir) in recent
    img = qimage_to_rgb(QImage(str(shot)))
    h, w, _ = img.shape
    assert w >= 1280 and h >= 800
    # The 3D view fills the top-left of the window; the plots run along the bottom-left.
    assert region_stats(img, (10, 40, int(w * 0.35), int(h * 0.5))).drawn
    assert region_stats(img, (10, int(h * 0.68), int(w * 0.6), int(h * 0.25))).drawn


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--dicom", "/no/such/folder"], "--dicom"),
        (["--plan", "/no/such/plan.json"], "--plan"),
        (["--quit-after-s", "0"], "--quit-after-s"),
        (["--screenshot", "out.jpg"], ".png"),
    ],
)
def test_cli_bad_arguments_exit_2(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from ctdrill.app.cli import main

    assert main(["gui", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err and "Traceback" not in err


def test_cli_folder_without_dicom_exits_2(tmp_path: Path) -> None:
    (tmp_path / "readme.txt").write_text("nothing here")
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "ctdrill.app.cli",
            "gui",
            "--dicom",
            str(tmp_path),
            "--quit-after-s",
            "30",
        ],
        cwd=ROOT,
        env={**os.environ, "XDG_CONFIG_HOME": str(tmp_path / "config")},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error:") and "Traceback" not in proc.stderr
