"""The window draws its first series before numba is imported (app/gui/first_draw.py), then
loads the kernels in the background; the path it drew is the one the loaded kernels give.
pydicom is not imported either: the demo's uncompressed series needs only the fast readers.
The objects the imports made are frozen for the garbage collector."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[3]

CODE = """
import gc, json, sys
from ctdrill.app.gui.preload import import_window

import_window()
imports = {"frozen": gc.get_freeze_count(), "collecting": gc.isenabled()}
from PySide6.QtCore import QSettings, QTimer

from ctdrill import jit
from ctdrill.app.gui import app as gui_app
from ctdrill.app.gui.results import compute_path_view
from ctdrill.imaging.plan.load import load_plan_set
from tests.test_jit_defer import fingerprint

settings = QSettings(sys.argv[1], QSettings.Format.IniFormat)
app = gui_app.application()
window = gui_app.make_window(settings)
window.unattended, window.ask_series = True, False
window.use_plans(load_plan_set(["assets/demo/plan.json"]), "plan")
window.open_folder("assets/demo/ct")
state = {}


def drawn():
    doc = window.doc
    state["at drawn"] = {
        "numba": "numba" in sys.modules,
        "pydicom": "pydicom" in sys.modules,  # an uncompressed series: the fast readers
        "steps": window.ui_steps.pending,
        "path": doc.path is not None and doc.path.plan is doc.plan,
        "slices": len(window.slices),
    }
    state["first"] = fingerprint(doc.path)
    loaded()


def loaded():
    if jit.deferred():
        QTimer.singleShot(20, loaded)
        return
    doc = window.doc
    state["ready"] = all(k.ready() for k in jit.kernels())
    view = compute_path_view(doc.volume, doc.plan, doc.hu_uncertainty, plan_set=doc.plans)
    state["same"] = fingerprint(view) == state.pop("first")
    frozen()


def frozen():
    from ctdrill.app.gui import preload

    if not preload._KERNELS_FROZEN[0]:
        QTimer.singleShot(20, frozen)
        return
    state["after kernels"] = {"frozen": gc.get_freeze_count(), "collecting": gc.isenabled()}
    app.quit()


window.first_draw.drawn.connect(drawn)
QTimer.singleShot(120_000, app.quit)
app.exec()
window.close()
state["imports"] = imports
print(json.dumps(state))
"""


def _run(code: str, tmp_path: Path) -> dict[str, Any]:
    """Run ``code`` in a fresh Python with private settings; the JSON of its last line."""
    out = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "settings.ini")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    state: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return state


def test_the_first_series_is_drawn_before_numba_loads_with_the_kernels_bits(
    tmp_path: Path,
) -> None:
    state = _run(CODE, tmp_path)
    assert state["at drawn"] == {
        "numba": False,
        "pydicom": False,
        "steps": 0,
        "path": True,
        "slices": 4,
    }
    assert state["ready"], "the warm-up's cache is missing: run make warmup"
    assert state["same"]
    # the window's imports are frozen for the collector (preload.import_window), which runs
    assert state["imports"]["frozen"] > 100_000 and state["imports"]["collecting"]
    # and once numba and the kernels loaded, what lives then (preload.freeze_kernels)
    after = state["after kernels"]
    assert after["frozen"] > state["imports"]["frozen"] + 50_000 and after["collecting"]


OPEN = """
import json, sys
from ctdrill import jit
from ctdrill.api import open_window
from PySide6.QtCore import QSettings

window = open_window(
    "assets/demo/ct", ["assets/demo/plan.json"],
    settings=QSettings(sys.argv[1], QSettings.Format.IniFormat),
)
loaded = [k.name for k in jit.kernels() if k._ready]
print(json.dumps({"deferred": jit.deferred(), "numba": "numba" in sys.modules, "n": len(loaded)}))
window.close()
"""


def test_open_window_returns_with_the_kernels_loaded(tmp_path: Path) -> None:
    """A script drives the window open_window returns with the compiled kernels (a drag from
    its first move), though they load after the first draw."""
    state = _run(OPEN, tmp_path)
    assert state["deferred"] is False and state["numba"] and state["n"] > 0
