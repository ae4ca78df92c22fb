"""Helpers shared by the window tests."""

from __future__ import annotations

from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging.phantom.io import PhantomCase

#: Longest wait for a load or a path computation, ms.
LOAD_TIMEOUT_MS = 30_000
#: Longest wait for a 2000-candidate search in the window, ms: a hang guard only (the search
#: takes a few seconds on idle cores and several times that on a shared, loaded machine).
SEARCH_TIMEOUT_MS = 240_000


def open_case(qtbot: QtBot, win: MainWindow, case: PhantomCase) -> None:
    """Open the case's plan and series and wait until the path and the bone surface are drawn."""
    win.open_plan(case.plan_path)
    with qtbot.waitSignal(win.path_updated, timeout=LOAD_TIMEOUT_MS):
        win.open_folder(case.ct_dir)
    # the bone surface is contoured after the slices and the path
    qtbot.waitUntil(win.view3d.surface_is_shown, timeout=LOAD_TIMEOUT_MS)
