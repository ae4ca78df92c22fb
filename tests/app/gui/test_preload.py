"""The window's Qt-free modules are imported before Qt (app/gui/preload.py)."""

from __future__ import annotations

import subprocess
import sys

from ctdrill.app.gui.preload import QT_FREE


def test_the_preloaded_modules_import_no_qt() -> None:
    code = (
        "import sys\n"
        "from ctdrill.app.gui.preload import before_qt\n"
        "before_qt()\n"
        "qt = sorted(m for m in sys.modules if m.split('.')[0] in ('PySide6', 'shiboken6'))\n"
        "print(qt)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.strip() == "[]", out.stdout
    assert "pyvista" in QT_FREE and "ctdrill.app.gui.compute" in QT_FREE
