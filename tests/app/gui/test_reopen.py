"""Opening a series again (or another one) under the same plan plans the path again: the
result of the previous volume is never kept for the new one."""

from __future__ import annotations

import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui


def test_reopening_the_series_computes_the_path_for_the_new_volume(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    before = window.doc.path
    first_volume = window.doc.volume
    assert before is not None
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(phantom_case.ct_dir)
    assert window.doc.volume is not first_volume
    assert window.doc.path is not None and window.doc.path is not before
