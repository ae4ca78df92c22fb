"""GUI fixtures: a written mandible phantom case and a main window with private settings."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from ctdrill.imaging.phantom.io import PhantomCase, write_phantom
from ctdrill.imaging.phantom.mandible import make_mandible_phantom


@pytest.fixture(scope="session")
def phantom_case(tmp_path_factory: pytest.TempPathFactory) -> PhantomCase:
    """The D2 mandible phantom (0.4 mm) written as DICOM with its plan and ground truth."""
    return write_phantom(tmp_path_factory.mktemp("case"), make_mandible_phantom(spacing_mm=0.4))


@pytest.fixture
def window(qtbot: object, tmp_path: Path) -> Iterator[object]:
    """A shown main window whose QSettings live in ``tmp_path``."""
    from PySide6.QtCore import QSettings

    from ctdrill.app.gui.app import make_window

    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    win = make_window(settings)
    win.unattended = True  # no modal dialog may block a test; bugs are collected instead
    qtbot.addWidget(win)  # type: ignore[attr-defined]
    yield win
    win.close()
    assert win.internal_error == "", win.internal_error
