"""The UI thread is given back between drawing steps: the step queue runs one step per
event-loop pass, and opening a case draws each canvas and the 3D frame in a pass of its own.

The stall itself (largest gap between ticks of a 5 ms timer while a case opens) is measured in
``bench/bench_gui.py``; on a shared 2-core machine its margin under the 100 ms goal is too thin
for a timed unit test, so these tests check the mechanism, which does not depend on load.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable

import pytest
from PySide6.QtCore import QTimer
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.workers import StepQueue
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case


def _busy(ms: float) -> None:
    end = time.perf_counter() + ms / 1000.0
    while time.perf_counter() < end:
        pass


def _ticker(log: list[str]) -> QTimer:
    """A zero-interval timer that logs ``"t"`` on every event-loop pass."""
    ticker = QTimer()
    ticker.setInterval(0)
    ticker.timeout.connect(lambda: log.append("t"))
    return ticker


def _steps_apart(log: list[str], prefix: str) -> bool:
    """True if a timer tick falls between every two consecutive entries starting with
    ``prefix``."""
    idx = [i for i, e in enumerate(log) if e.startswith(prefix)]
    return all("t" in log[a + 1 : b] for a, b in itertools.pairwise(idx))


def test_step_queue_runs_in_order_one_step_per_pass(qtbot: QtBot) -> None:
    queue = StepQueue()
    log: list[str] = []
    ticker = _ticker(log)
    ticker.start()

    def step(name: str) -> Callable[[], None]:
        def run() -> None:
            log.append(name)
            _busy(10.0)

        return run

    for name in ("s1", "s2", "s3", "s4"):
        queue.push(step(name))
    assert queue.pending == 4
    qtbot.waitUntil(lambda: queue.pending == 0 and "s4" in log, timeout=LOAD_TIMEOUT_MS)
    ticker.stop()
    assert [e for e in log if e != "t"] == ["s1", "s2", "s3", "s4"]
    assert _steps_apart(log, "s")


def test_step_queue_takes_steps_pushed_by_a_step(qtbot: QtBot) -> None:
    queue = StepQueue()
    log: list[str] = []

    def first() -> None:
        log.append("a")
        queue.push(lambda: log.append("c"))

    queue.push(first)
    queue.push(lambda: log.append("b"))
    qtbot.waitUntil(lambda: len(log) == 3, timeout=LOAD_TIMEOUT_MS)
    assert log == ["a", "b", "c"]
    assert queue.pending == 0


@pytest.mark.timeout(120)
def test_opening_a_case_draws_each_view_in_its_own_pass(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    log: list[str] = []
    for name, canvas in window.slice_canvases.items():
        draw = canvas.draw

        def logged(draw: Callable[[], None] = draw, name: str = name) -> None:
            log.append(f"draw {name}")
            draw()

        canvas.draw = logged  # type: ignore[method-assign]
    render = window.view3d.render_now

    def logged_render() -> None:
        log.append("3d frame asked")  # drawn on the view's render thread, not in a pass
        render()

    window.view3d.render_now = logged_render  # type: ignore[method-assign]
    ticker = _ticker(log)
    ticker.start()
    open_case(qtbot, window, phantom_case)
    qtbot.waitUntil(lambda: window.ui_steps.pending == 0, timeout=LOAD_TIMEOUT_MS)
    ticker.stop()
    drawn = [e for e in log if e != "t"]
    assert set(drawn) >= {
        "draw axial",
        "draw coronal",
        "draw sagittal",
        "draw trajectory",
        "3d frame asked",
    }
    assert _steps_apart(log, "draw")  # the slice views, each in a pass of its own
