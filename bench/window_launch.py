"""Fresh-process driver of ``bench_window``: runs ``ctdrill gui --ct CT --plan PLAN`` through the
command line's own ``main`` (as the ``ctdrill`` entry point does) and prints, as one JSON line,
when the window and each of its views were first drawn, in seconds since the parent launched
this process, with the process's CPU time then.

Usage: ``python -m bench.window_launch LAUNCH_EPOCH_S CT PLAN``. The window is watched from
the moment the command line has imported it (:func:`~ctdrill.app.gui.preload.import_window`),
so the command line runs in its own order (the series read beside those imports).
"""

from __future__ import annotations

import gc
import itertools
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
    gc.callbacks.append(_gc_timed)
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


_GC_START: list[float] = [0.0]


def _gc_timed(phase: str, info: dict[str, int]) -> None:
    """Sum the garbage collector's pauses (every thread waits) until the views are drawn."""
    if phase == "start":
        _GC_START[0] = time.perf_counter()
    elif "views drawn" not in marks:
        pause = time.perf_counter() - _GC_START[0]
        marks["gc pauses to views drawn"] = marks.get("gc pauses to views drawn", 0.0) + pause


def watch(gui_app: Any) -> None:
    """Mark when the window made by ``gui_app.make_window`` and each of its views is drawn,
    then when the compiled kernels have loaded (in the background, after the first draw) with
    the longest gap between ticks of a 5 ms timer on the UI thread meanwhile."""
    make_window = gui_app.make_window
    from ctdrill import jit

    def watched(*args: object, **kw: object) -> object:
        window = make_window(*args, **kw)
        marks["window shown"] = _since_launch()
        from PySide6.QtCore import QTimer

        seen: set[str] = set()
        ticks: list[float] = []
        beat = QTimer()
        beat.setInterval(5)
        beat.timeout.connect(lambda: ticks.append(time.perf_counter()))

        def done() -> bool:
            return "3D settled" in marks and "kernels loaded" in marks

        def kernels() -> None:  # polled from the views drawn until the kernels are loaded
            if jit.deferred():
                QTimer.singleShot(10, kernels)
                return
            ticks.append(time.perf_counter())
            beat.stop()
            marks["kernels loaded"] = _since_launch()
            gaps = [b - a for a, b in itertools.pairwise(ticks)]
            marks["longest UI gap while kernels load"] = max(gaps, default=0.0)
            if done():
                gui_app.application().quit()

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
                marks["numba imported at views drawn"] = float("numba" in sys.modules)
                ticks.append(time.perf_counter())
                beat.start()
                kernels()

        def settled() -> None:
            marks.setdefault("3D settled", _since_launch())
            if done():
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
