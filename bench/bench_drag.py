"""Planning at the speed of a drag (issues 27 and 37): from a mouse move to the repainted force
plot, with real Qt mouse events on the window, idle and beside two busy processes, against the
older chain measured in the same run.

Cases: the bundled demo phantom and a synthetic 640 x 640 x 480 series (0.2 mm voxels, a bone
bar with a cortical shell and a canal 16 mm below its top, the drill 14.5 mm long:
``bench.bench_gui.synthetic_case``). The window is
opened by ``ctdrill.api``'s ``open_window`` and driven through ``QTest`` mouse events on
``view:drill`` (the drill's target grip); the time is read when ``plot:force`` says it has drawn
the new curves (its ``stopDepthMmChanged``, emitted by the paint that puts them on the screen).

- **live** (today): mouse moves are coalesced to the latest; each previews the dragged plan:
  its curves and stop are computed at once in a worker (one at a time, the latest next) and
  painted over the kept axes (a pixmap) by the paint that shows them; the implant's check,
  the problems and the readout follow in a second worker (one at a time, the latest position
  whose curves came, at most every 100 ms during the drag), so the next curves never wait for
  them; the dragged outline and the cursor's readout are drawn with the curves of their
  position (one window update a position).
  *Latency*: from rest (nothing computing), a move, then the time until the plot is repainted
  with that move's curves; one move at a time.
  *Continuous drag*: a 60 Hz mouse (a move every 16 ms, a triangle wave of 0.25 mm steps
  over 5 mm, in whole pixels of the drill view) for a few seconds: repaints of the force
  plot per second, the moves Qt delivered per second, and the **lag** of each repaint: the
  time since the mouse was at the position it draws (median and 90th percentile). Each
  repaint's position is checked against the order of the mouse (never an older one after a
  newer) and each computation against the latest position when it started (``latest next``).
  Both idle and beside two busy processes (``python -c 'while 1: pass'``, started here) that
  take the 2 cores' time.
- **older chain** (:func:`older_chain`, the window before issue 27, rebuilt here from the
  window's own options: the product keeps none of it): the plan changes only at the release
  (the canvases' ``live_drag`` off), the path waits :data:`LEGACY_DEBOUNCE_MS` (150 ms) and
  the plots are drawn after the 3D view and the slice redraws (their drawing steps queued
  last). Latency: the release of a short
  drag, then the time until the plots show its curves.

The breakdown (each median): the dragged plan's checks in their worker (the implant's check
and the problems, after its curves) with the CPU time its thread spent (the rest of the wall
time is waiting for a core or the interpreter lock), the curves in theirs, the
force plot's paint with new curves on the UI thread (its CPU time), the dragged view's
outline; and the UI thread's CPU time over the continuous drag per repaint, and the paints per
mouse move of the drill view, the force plot, the other slices and the 3D view (an event
filter on each: a move repaints only the views it changes). Every update of this window is
composited whole through Qt's RHI (the 3D view is an OpenGL widget), on the CPU under Xvfb:
``perf`` on the UI thread during a 60 Hz drag put a quarter of its CPU time there
(``QPlatformBackingStore::rhiFlush``). Under Xvfb with software OpenGL (Mesa llvmpipe) when run
by ``make bench``; the 3D view and the slice contours catch up after the release.
"""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bench.bench_gui import synthetic_case
from bench.report import Section, Timing, figure_path, headline_row, table

ROOT = Path(__file__).resolve().parents[1]
#: The wait the window used after an edit before live editing, ms (the older chain's).
LEGACY_DEBOUNCE_MS = 150


def older_chain(window: Any, on: bool) -> None:
    """Put ``window`` in the older chain (``on``) or back to today's: the canvases report a
    drag only at its release, the controller waits :data:`LEGACY_DEBOUNCE_MS`, and every
    drawing step is queued after the others (the plots lose their place at the front)."""
    from ctdrill.app.gui.controller import DEBOUNCE_MS
    from ctdrill.app.gui.map_canvas import MapCanvas

    window.controller.set_debounce(LEGACY_DEBOUNCE_MS if on else DEBOUNCE_MS)
    for canvas in window.findChildren(MapCanvas):
        canvas.live_drag = not on
    steps = window.ui_steps
    if on:
        push = steps.push
        steps.push = lambda fn, *, first=False: push(fn, first=False)
    else:
        steps.__dict__.pop("push", None)


DEMO = ROOT / "assets" / "demo"
#: Goals of issue 37: a move to the repainted force plot (median, idle), repaints per second
#: beside two busy processes.
GOAL_LATENCY_MS = 16.0
GOAL_RATE_HZ = 20.0
#: Mouse step per move down the drill view (the plan goes deeper), mm: the continuous drag's
#: wave spans ``WAVE_STEPS * STEP_MM`` = 5 mm on every case, whatever the view's scale, so the
#: dragged plans stay dental ones (not past the canal) on a large field of view too.
STEP_MM = 0.25
#: The continuous drag's triangle wave, in steps (up and back).
WAVE_STEPS = 20
#: The synthetic case's canal below the bone's top, mm: a dental path (entry 1 mm above the
#: bone, target 2.5 mm above the canal: 14.5 mm), as the demo's 12 mm.
CANAL_BELOW_TOP_MM = 16.0
#: The synthetic series' voxel size, mm.
SYNTHETIC_MM = 0.2
#: Busy processes beside the window in the loaded runs.
BUSY = 2
LOADS = (("idle", 0), (f"{BUSY} busy processes", BUSY))


def _wait(app: Any, done: Callable[[], bool], timeout_s: float = 60.0) -> bool:
    """Run the event loop (blocking between events, as a window's does) until ``done()``,
    checked every millisecond; False on timeout."""
    from PySide6.QtCore import QEventLoop, QTimer

    if done():
        return True
    t0 = time.perf_counter()
    loop = QEventLoop()
    ok = {"done": False}

    def check() -> None:
        if done():
            ok["done"] = True
            loop.quit()
        elif time.perf_counter() - t0 > timeout_s:
            loop.quit()

    timer = QTimer()
    timer.setInterval(1)
    timer.timeout.connect(check)
    timer.start()
    loop.exec()
    timer.stop()
    return ok["done"]


class _Probe:
    """Times the chain's parts (the worker's path computation, its curves, the plots' redraw,
    the dragged view's outline) and ties each dragged plan to the mouse move it came from
    (wrappers around the window's own calls)."""

    def __init__(self, window: Any) -> None:
        import ctdrill.app.gui.controller as controller
        import ctdrill.app.gui.plan_editor as plan_editor
        import ctdrill.app.gui.results as results

        self.compute: list[float] = []
        self.compute_cpu: list[float] = []
        self.curves: list[float] = []
        self.curves_cpu: list[float] = []
        self.plots: list[float] = []
        self.ghost: list[float] = []
        #: id(plan) -> index of the mouse move it was dragged to (the latest sent).
        self.move_of: dict[int, int] = {}
        self.sent = 0
        restore: list[Callable[[], None]] = []
        original = controller.completed_view

        def timed_checks(*args: Any, **kw: Any) -> Any:
            t0, c0 = time.perf_counter(), time.thread_time()
            out = original(*args, **kw)
            self.compute.append(time.perf_counter() - t0)
            self.compute_cpu.append(time.thread_time() - c0)
            return out

        controller.completed_view = timed_checks
        restore.append(lambda: setattr(controller, "completed_view", original))
        curves = results.path_curves

        def timed_curves(*args: Any, **kw: Any) -> Any:
            t0, c0 = time.perf_counter(), time.thread_time()
            out = curves(*args, **kw)
            self.curves.append(time.perf_counter() - t0)
            self.curves_cpu.append(time.thread_time() - c0)
            return out

        results.path_curves = timed_curves
        restore.append(lambda: setattr(results, "path_curves", curves))
        dragged = plan_editor.dragged_plan

        def tagged(*args: Any, **kw: Any) -> Any:
            plan = dragged(*args, **kw)
            self.move_of[id(plan)] = self.sent
            return plan

        plan_editor.dragged_plan = tagged
        restore.append(lambda: setattr(plan_editor, "dragged_plan", dragged))
        self._restore = restore
        plots = window.plot_canvas

        def painted(_stop: float) -> None:  # the paint that put new curves on the screen
            if window.doc.live.dragging:
                self.plots.append(plots.paint_cpu_s)

        plots.stopDepthMmChanged.connect(painted)
        restore.append(lambda: plots.stopDepthMmChanged.disconnect(painted))
        drill = window.slice_canvases["trajectory"]
        ghost = drill.draw_ghost_of

        def timed_ghost(*args: Any) -> None:
            t0 = time.perf_counter()
            ghost(*args)
            self.ghost.append(time.perf_counter() - t0)

        drill.draw_ghost_of = timed_ghost

    def close(self) -> None:
        for fn in self._restore:
            fn()


def _wait_drawn(plot: Any, timeout_s: float = 60.0) -> bool:
    """Run the event loop until ``plot`` is repainted with new curves (no polling, so the
    UI thread's CPU time is the window's own); False on timeout."""
    from PySide6.QtCore import QEventLoop, QTimer

    loop = QEventLoop()
    ok = {"done": False}

    def drawn(_v: float) -> None:
        ok["done"] = True
        loop.quit()

    plot.stopDepthMmChanged.connect(drawn)
    QTimer.singleShot(int(timeout_s * 1e3), loop.quit)
    loop.exec()
    plot.stopDepthMmChanged.disconnect(drawn)
    return ok["done"]


def _paint_counter(window: Any) -> Any:
    """An event filter counting the paint events of the drill view, the force plot, the 3D
    view and the other slices (``install`` / ``remove`` on them; ``per_move``)."""
    from PySide6.QtCore import QEvent, QObject
    from PySide6.QtWidgets import QWidget

    views = {
        "drill": ["view:drill"],
        "plot": ["plot:force"],
        "other slices": ["view:axial", "view:coronal", "view:sagittal"],
    }
    widgets = {k: [window.findChild(QWidget, n) for n in names] for k, names in views.items()}
    widgets["3D"] = [window.view3d]
    of = {id(w): k for k, ws in widgets.items() for w in ws if w is not None}

    class Counter(QObject):
        def __init__(self) -> None:
            super().__init__()
            self.counts = dict.fromkeys(widgets, 0)

        def eventFilter(self, obj: QObject, event: QEvent) -> bool:
            if event.type() == QEvent.Type.Paint and id(obj) in of:
                self.counts[of[id(obj)]] += 1
            return False

        def install(self, on: bool) -> None:
            for ws in widgets.values():
                for w in ws:
                    if w is not None:
                        (w.installEventFilter if on else w.removeEventFilter)(self)

        def per_move(self, moves: int) -> str:
            """Paints per mouse move of each view."""
            return ", ".join(f"{k} {n / max(1, moves):.2f}" for k, n in self.counts.items())

    return Counter()


#: The UI thread's idle time before each timed wake-up, ms.
WAKEUP_AFTER_MS = 3


def ui_wakeups(switch_s: float, n: int = 200) -> Timing:
    """How late a wake-up of the UI thread (a timer of :data:`WAKEUP_AFTER_MS`, the event loop
    idle until then) comes while a worker thread runs Python, at the interpreter switch
    interval ``switch_s``."""
    import threading

    from PySide6.QtCore import QEventLoop, QTimer

    stop = threading.Event()

    def spin() -> None:  # pure Python, as the path's glue and the checks are between kernels
        x = 0
        while not stop.is_set():
            x += 1

    old = sys.getswitchinterval()
    sys.setswitchinterval(switch_s)
    worker = threading.Thread(target=spin, daemon=True)
    worker.start()
    late = []
    try:
        loop = QEventLoop()
        for _ in range(n):
            t0 = time.perf_counter()
            QTimer.singleShot(WAKEUP_AFTER_MS, loop.quit)
            loop.exec()
            late.append(time.perf_counter() - t0 - WAKEUP_AFTER_MS / 1e3)
    finally:
        stop.set()
        worker.join()
        sys.setswitchinterval(old)
    return Timing.from_samples(late)


def _busy(n: int) -> list[subprocess.Popen[bytes]]:
    return [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(n)]


def _step_px(drill: Any, plan: Any) -> int:
    """Widget pixels of :data:`STEP_MM` along the drill on the drill view (its scale from the
    plan's entry and target as drawn), at least 1."""
    a = np.asarray(drill.lps_to_pixel(plan.entry_lps), dtype=float)
    b = np.asarray(drill.lps_to_pixel(plan.target_lps), dtype=float)
    depth_mm = float(np.linalg.norm(np.asarray(plan.target_lps) - np.asarray(plan.entry_lps)))
    return max(1, round(STEP_MM * float(np.linalg.norm(b - a)) / depth_mm))


def _measure(
    window: Any, probe: _Probe, moves: int, rate_s: float, shot: Path | None
) -> dict[str, Any]:
    """One press, ``moves`` timed moves from rest, a continuous 60 Hz drag for ``rate_s``,
    the release and its undo."""
    from PySide6.QtCore import QPoint, Qt, QTimer
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QApplication, QWidget

    app = QApplication.instance()
    drill = window.findChild(QWidget, "view:drill")
    plot = window.findChild(QWidget, "plot:force")
    live, ctl = window.doc.live, window.controller
    drawn: list[tuple[float, int]] = []  # (time, move index drawn)

    def on_drawn(_v: float) -> None:
        view = live.curves
        move = -1 if view is None else probe.move_of.get(id(view.plan), -1)
        drawn.append((time.perf_counter(), move))

    plot.stopDepthMmChanged.connect(on_drawn)
    left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier
    paints = _paint_counter(window)

    def at_rest() -> bool:
        runners = (ctl.live_runner, ctl.check_runner, ctl.readout_runner, ctl.path_runner)
        busy = any(r.busy for r in runners)
        return not busy and window.ui_steps.pending == 0

    try:
        grip = drill.lps_to_pixel(window.doc.plan.target_lps)
        x, y = round(grip[0]), round(grip[1])
        step_px = _step_px(drill, window.doc.plan)
        QTest.mousePress(drill, left, none, QPoint(x, y))
        _wait(app, lambda: live.path is not None)  # the press previews the plan
        latency, latency_cpu = [], []
        for k in range(1, moves + 1):
            _wait(app, at_rest)
            m = len(probe.curves_cpu)
            probe.sent += 1
            t0, c0 = time.perf_counter(), time.thread_time()
            QTest.mouseMove(drill, QPoint(x, y + step_px * (k % WAVE_STEPS)))
            if _wait_drawn(plot):
                latency.append(drawn[-1][0] - t0)
                # the UI thread's CPU from the move to the repaint, and the worker's curves
                ui = time.thread_time() - c0
                latency_cpu.append(ui + sum(probe.curves_cpu[m:]))
        _wait(app, at_rest)
        sent_t: dict[int, float] = {}
        n0 = len(drawn)
        state = {"k": 0}

        def move() -> None:
            state["k"] += 1
            k = state["k"] % (2 * WAVE_STEPS)
            step = k if k <= WAVE_STEPS else 2 * WAVE_STEPS - k
            probe.sent += 1
            sent_t[probe.sent] = time.perf_counter()
            QTest.mouseMove(drill, QPoint(x, y + step_px * step))

        timer = QTimer()
        timer.setInterval(16)
        timer.timeout.connect(move)
        t0, c0 = time.perf_counter(), time.thread_time()
        paints.install(True)
        timer.start()
        if shot is not None:
            _wait(app, lambda: time.perf_counter() - t0 > rate_s / 2, timeout_s=rate_s)
            grab = window.grab()  # half size: enough to see the outline, the plots, the banner
            grab.scaledToWidth(grab.width() // 2, Qt.TransformationMode.SmoothTransformation).save(
                str(shot)
            )
        _wait(app, lambda: time.perf_counter() - t0 > rate_s, timeout_s=rate_s + 5)
        timer.stop()
        elapsed = time.perf_counter() - t0
        ui_cpu_s = time.thread_time() - c0
        paints.install(False)
        during = drawn[n0:]
        lags = [t - sent_t[m] for t, m in during if m in sent_t]
        order = [m for _, m in during]
        out_of_order = sum(1 for a, b in itertools.pairwise(order) if b < a)
        QTest.mouseRelease(drill, left, none, QPoint(x, y))
        _wait(app, lambda: at_rest() and not ctl.path_runner.busy)
        window.undo_action.trigger()
        _wait(app, at_rest)
    finally:
        plot.stopDepthMmChanged.disconnect(on_drawn)
    return {
        "latency": Timing.from_samples(latency or [np.nan]),
        "latency_p90_s": float(np.percentile(latency, 90)) if latency else np.nan,
        "latency_cpu": Timing.from_samples(latency_cpu or [np.nan]),
        "rate_hz": len(during) / elapsed,
        "sent_hz": state["k"] / elapsed,
        "lag": Timing.from_samples(lags or [np.nan]),
        "lag_p90_s": float(np.percentile(lags, 90)) if lags else np.nan,
        "out_of_order": out_of_order,
        "repaints": len(during),
        "ui_cpu_s": ui_cpu_s / max(1, len(during)),
        "paints": paints.per_move(state["k"]),
    }


def _drag_case(
    ct_dir: Path,
    plan_path: Path,
    moves: int,
    legacy_steps: int,
    rate_s: float,
    settle: bool,
    name: str,
) -> dict[str, Any]:
    """Drag on one case (``settle``: first wait for the 3D view's finest surface)."""
    from PySide6.QtCore import QPoint, QSettings, Qt
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QApplication, QWidget

    from ctdrill.app.gui.api import open_window

    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-drag-") as tmp:
        settings = QSettings(str(Path(tmp) / "s.ini"), QSettings.Format.IniFormat)
        window = open_window(ct_dir, [plan_path], settings=settings)
    app = QApplication.instance()
    if settle:  # the 3D view's finer surfaces are contoured in the background: after them
        _wait(app, lambda: bool(np.isfinite(window.view3d.settled_s)), timeout_s=600.0)
    _wait(app, lambda: window.ui_steps.pending == 0)
    from ctdrill import jit

    # the kernels load once the window has drawn the case (gui/first_draw.py): the drag after
    _wait(app, lambda: not jit.deferred())
    from ctdrill.app.gui.plots_view import PlotsView
    from ctdrill.app.gui.slice_view import SliceCanvas

    drill = window.findChild(QWidget, "view:drill")
    plot = window.findChild(QWidget, "plot:force")
    assert isinstance(drill, SliceCanvas) and isinstance(plot, PlotsView)
    assert window.doc.plan is not None
    left = Qt.MouseButton.LeftButton
    none = Qt.KeyboardModifier.NoModifier
    probe = _Probe(window)
    runs: dict[str, dict[str, Any]] = {}
    try:
        for load_name, busy in LOADS:
            procs = _busy(busy)
            try:
                time.sleep(0.5 if busy else 0.0)
                shot = figure_path(f"drag_{name}.png") if settle and busy else None
                runs[load_name] = _measure(window, probe, moves, rate_s, shot)
                runs[load_name]["load"] = os.getloadavg()[0]
            finally:
                for proc in procs:
                    proc.kill()
                    proc.wait()
        parts = {
            "checks in the worker (implant, problems)": Timing.from_samples(
                probe.compute or [np.nan]
            ),
            "its CPU time": Timing.from_samples(probe.compute_cpu or [np.nan]),
            "curves in the worker": Timing.from_samples(probe.curves or [np.nan]),
            "force plot painted (live), CPU": Timing.from_samples(probe.plots or [np.nan]),
            "dragged outline": Timing.from_samples(probe.ghost or [np.nan]),
        }
        # the older chain: a short drag, its release, the plots
        drawn: list[float] = []
        plot.stopDepthMmChanged.connect(lambda _v: drawn.append(time.perf_counter()))
        older_chain(window, True)
        older = []
        for k in range(legacy_steps):
            plan = window.doc.plan
            grip = None if plan is None else drill.lps_to_pixel(plan.target_lps)
            assert grip is not None
            x, y = round(grip[0]), round(grip[1])
            dy = _step_px(drill, plan) * (1 + k % 3)
            QTest.mousePress(drill, left, none, QPoint(x, y))
            QTest.mouseMove(drill, QPoint(x, y + dy))
            n = len(drawn)
            t0 = time.perf_counter()
            QTest.mouseRelease(drill, left, none, QPoint(x, y + dy))
            if _wait(app, lambda n=n: len(drawn) > n):  # type: ignore[misc]
                older.append(drawn[-1] - t0)
            _wait(app, lambda: window.ui_steps.pending == 0)
        older_chain(window, False)
        volume = window.doc.volume
        dims = "x".join(str(d) for d in volume.dims) if volume is not None else "?"
    finally:
        probe.close()
        window.close()
    return {
        "dims": dims,
        "runs": runs,
        "older": Timing.from_samples(older or [np.nan]),
        "parts": parts,
        "shot": figure_path(f"drag_{name}.png") if settle else None,
    }


def run(quick: bool) -> Section:
    """Drag the target on the drill view of the demo and of a 640 x 640 x 480 series."""
    moves, legacy, rate_s = (3, 1, 0.3) if quick else (30, 6, 4.0)
    results: dict[str, dict[str, Any]] = {}
    results["demo"] = _drag_case(
        DEMO / "ct", DEMO / "plan.json", moves, legacy, rate_s, not quick, "demo"
    )
    from ctdrill.app.gui.controller import UI_SWITCH_INTERVAL_S

    wakeups = {s: ui_wakeups(s, 20 if quick else 200) for s in (0.005, UI_SWITCH_INTERVAL_S)}
    write_s = 0.0
    if not quick:
        with tempfile.TemporaryDirectory(prefix="ctdrill-bench-drag-big-") as tmp:
            t0 = time.perf_counter()
            plan = synthetic_case(
                Path(tmp), (480, 640, 640), SYNTHETIC_MM, canal_below_top_mm=CANAL_BELOW_TOP_MM
            )
            write_s = time.perf_counter() - t0
            results["synthetic 640x640x480"] = _drag_case(
                Path(tmp) / "ct", plan, moves, legacy, rate_s, True, "synthetic"
            )
    rows, part_rows, headline, shortfalls, shots = [], [], [], [], []
    for name, r in results.items():
        older = r["older"]
        idle = r["runs"]["idle"]
        busy = r["runs"][LOADS[1][0]]
        ratio = older.median_s / idle["latency"].median_s
        for load_name, m in r["runs"].items():
            rows.append(
                [
                    name,
                    r["dims"],
                    load_name,
                    f"{m['load']:.1f}",
                    m["latency"].fmt("ms") + f" p90 {1e3 * m['latency_p90_s']:.3g}",
                    m["latency_cpu"].fmt("ms"),
                    f"{m['rate_hz']:.1f} (mouse {m['sent_hz']:.0f}/s)",
                    m["lag"].fmt("ms") + f" p90 {1e3 * m['lag_p90_s']:.3g}",
                    f"{m['out_of_order']} of {m['repaints']}",
                    f"{1e3 * m['ui_cpu_s']:.1f} ms",
                    m["paints"],
                ]
            )
        part_rows.append([name, *(t.fmt("ms") for t in r["parts"].values())])
        headline.append(
            headline_row(
                f"drag: mouse move to repainted force plot, {name} (idle)",
                idle["latency"].fmt("ms"),
                f"older chain (release to plots) {older.fmt('ms')}",
                f"{ratio:.1f}",
                f"<= {GOAL_LATENCY_MS:g} ms median idle",
            )
        )
        headline.append(
            headline_row(
                f"drag: repaints/s at a 60 Hz mouse, {name}, beside {BUSY} busy processes",
                f"{busy['rate_hz']:.1f}/s (lag {1e3 * busy['lag'].median_s:.0f} ms)",
                f"idle {idle['rate_hz']:.1f}/s (lag {1e3 * idle['lag'].median_s:.0f} ms)",
                "",
                f">= {GOAL_RATE_HZ:g}/s, the latest next",
            )
        )
        if 1e3 * idle["latency"].median_s > GOAL_LATENCY_MS:
            shortfalls.append(
                f"drag on {name}: {1e3 * idle['latency'].median_s:.0f} ms from a mouse move "
                f"to the repainted force plot (median, idle, load {idle['load']:.1f}) against "
                f"the {GOAL_LATENCY_MS:g} ms goal"
            )
        if busy["rate_hz"] < GOAL_RATE_HZ:
            shortfalls.append(
                f"drag on {name}: {busy['rate_hz']:.1f} repaints/s beside {BUSY} busy "
                f"processes (load {busy['load']:.1f}) against {GOAL_RATE_HZ:g}"
            )
        if r["shot"] is not None:
            shots.append(r["shot"])
    notes = [
        __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
        f"{moves} timed moves of {STEP_MM:g} mm (whole pixels of the drill view) from rest, "
        f"a {rate_s:g} s continuous drag, "
        f"and {legacy} older-chain drags per case and load"
        + ("" if quick else f"; the synthetic series took {write_s:.0f} s to write (not timed)")
        + ". The load column is the machine's 1-minute load average at the end of the run (2 "
        "cores shared with other work, the busy processes included): the chain runs in two "
        "threads and competes for them. *idle* means no busy process started here; the load "
        "says what else ran. The CPU time of a move (the UI thread's from the move to the "
        "repaint, plus the worker's for the curves) is what the latency would be on cores of "
        "its own.",
        table(
            [
                "case",
                "dims",
                "beside",
                "load (1 min)",
                "move to repainted plot (from rest)",
                "its CPU time (UI thread + curves)",
                "repaints/s (60 Hz mouse)",
                "lag of the drawn position",
                "drawn out of order",
                "UI thread CPU per repaint",
                "paints per mouse move (60 Hz drag)",
            ],
            rows,
        ),
        table(
            [
                "case",
                "checks in the worker (implant, problems)",
                "its CPU time",
                "curves in the worker",
                "force plot painted (live), CPU",
                "dragged outline",
            ],
            part_rows,
        ),
        f"How late a wake-up of the UI thread (a {WAKEUP_AFTER_MS} ms timer, the event loop idle "
        "until then) comes while a worker thread runs Python: "
        + "; ".join(
            f"{t.fmt('ms')} at a switch interval of {1e3 * s:g} ms"
            + (" (Python's default)" if s == 0.005 else " (the window's, ``UI_SWITCH_INTERVAL_S``)")
            for s, t in wakeups.items()
        )
        + f" (load {os.getloadavg()[0]:.1f}).",
        "Older chain, release to plots: "
        + "; ".join(f"{n} {r['older'].fmt('ms')}" for n, r in results.items())
        + ".",
    ]
    if shots:
        notes.append(
            f"The window mid-drag beside {BUSY} busy processes (the dragged outline in white on "
            "the drill view, the plots and the banner of the position drawn): "
            + ", ".join(f"`{Path(shot).name}`" for shot in shots)
            + "."
        )
    return Section(
        title="Dragging a plan (bench_drag)",
        markdown="\n\n".join(notes),
        figures=tuple(str(shot) for shot in shots),
        shortfalls=tuple(shortfalls),
        headline=tuple(headline),
    )
