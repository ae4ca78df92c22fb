"""Fresh-process driver of ``bench_window``: runs ``ctdrill gui --ct CT --plan PLAN`` through the
command line's own ``main`` (as the ``ctdrill`` entry point does) and prints, as one JSON line,
when the window and each of its views were first drawn, in seconds since the parent launched
this process, with the process's CPU time then.

Usage: ``python -m bench.window_launch LAUNCH_EPOCH_S CT PLAN``. The window is watched from
the moment the command line has imported it (:func:`~ctdrill.app.gui.preload.import_window`),
so the command line runs in its own order (the series read beside those imports).
"""

from __future__ import annotations

import json
import os
import sys
import time
from typing import Any

LAUNCH_S = float(sys.argv[1])


#: When each mark was reached, s since the launch (the CPU time to the views drawn, s).
marks: dict[str, float] = {}


def _since_launch() -> float:
    return time.time() - LAUNCH_S


def _cpu_s() -> float:
    t = os.times()
    return t.user + t.system


def main() -> int:
    """Run the window until every view has drawn the case, then quit and print the times."""
    ct, plan = sys.argv[2], sys.argv[3]
    marks["started"] = _since_launch()
    from ctdrill.app.cli import main as cli_main
    from ctdrill.app.gui import preload

    import_window = preload.import_window

    def imports() -> None:  # the command line's own order: the window is watched from here
        import_window()
        from ctdrill.app.gui import app as gui_app

        watch(gui_app)

    preload.import_window = imports
    code = cli_main(["gui", "--ct", ct, "--plan", plan, "--quit-after-s", "300"])
    marks["exit code"] = float(code)
    print(json.dumps(marks))
    return 0


def watch(gui_app: Any) -> None:
    """Mark when the window made by ``gui_app.make_window`` and each of its views is drawn."""
    make_window = gui_app.make_window

    def watched(*args: object, **kw: object) -> object:
        window = make_window(*args, **kw)
        marks["window shown"] = _since_launch()
        from PySide6.QtCore import QTimer

        seen: set[str] = set()

        def mark(what: str) -> None:
            if what not in marks:
                marks[what] = _since_launch()
            seen.add(what)
            if {"slices", "path", "3D surface"} <= seen:
                drained()

        def drained() -> None:
            if window.ui_steps.pending:
                QTimer.singleShot(1, drained)
                return
            if "views drawn" not in marks:
                marks["views drawn"] = _since_launch()
                marks["cpu to views drawn"] = _cpu_s()
            if "3D settled" in marks:
                gui_app.application().quit()

        def settled() -> None:
            marks.setdefault("3D settled", _since_launch())
            if "views drawn" in marks:
                gui_app.application().quit()

        QTimer.singleShot(0, lambda: marks.setdefault("window painted", _since_launch()))
        window.slices_updated.connect(lambda: mark("slices"))
        window.path_updated.connect(lambda: mark("path"))
        window.path_failed.connect(lambda _m: mark("path"))
        window.view3d.surface_shown.connect(lambda: mark("3D surface"))
        window.view3d.surface_settled.connect(settled)
        return window

    gui_app.make_window = watched


if __name__ == "__main__":
    sys.exit(main())
