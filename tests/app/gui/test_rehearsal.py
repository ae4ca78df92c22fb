"""A simulated rehearsal from the window: arm, push, reach the auto-stop, export."""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.rehearsal import SIMULATOR, clearance_at_mm, device_choices
from ctdrill.app.gui.rehearsal_live import STATE_WORDS
from ctdrill.engine.path import plan_path
from ctdrill.imaging import load_series
from ctdrill.imaging.phantom.io import PhantomCase
from ctdrill.imaging.plan.load import load_plan
from ctdrill.model import load_calibration
from tests.app.gui.helpers import open_case
from tests.haptics.emulator_process import HostLate, host_late, with_fresh_emulator

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def test_device_choices_start_with_the_simulator() -> None:
    choices = device_choices()
    assert choices[0] == SIMULATOR
    assert all(c.startswith("serial:") for c in choices[1:])


def test_clearance_at_the_live_depth_interpolates_the_path(phantom_case: PhantomCase) -> None:
    plan = load_plan(phantom_case.plan_path)
    result = plan_path(load_series(phantom_case.ct_dir), plan, load_calibration(plan.calibration))
    # Canal top at z = -41.8, entry at z = -29: the tip is 12.8 - x above it (vertical drill,
    # canal directly below), so clearance(x) = 12.8 - x.
    for depth in (0.0, 3.3, 10.8):
        assert clearance_at_mm(result, depth) == pytest.approx(12.8 - depth, abs=0.01)


def test_simulated_rehearsal_reaches_the_auto_stop_and_exports(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    assert panel.connect_button.isEnabled()
    panel.realtime = False
    panel.duration_s = 60.0  # the session ends at the auto-stop, long before
    panel.hand.set_push(12.0)
    panel.device.setCurrentText(SIMULATOR)
    with qtbot.waitSignal(panel.finished, timeout=60_000):
        qtbot.mouseClick(panel.connect_button, Qt.MouseButton.LeftButton)
    run = panel.run
    assert run is not None and run.error == "" and run.session is not None
    stop = window.view.curves.stop_depth_mm if window.view is not None else np.nan
    drill = np.array([r[2] for r in run.rows])
    states = [r[4] for r in run.rows]
    assert "cutting" in states and "stopped" in states
    # The device held the drill at the stop depth: never past it by more than 0.05 mm.
    assert drill.max() == pytest.approx(stop, abs=0.05)
    assert run.session["max_drill_mm"] <= stop + 0.05
    first_stop = states.index("stopped")
    assert drill[first_stop] == pytest.approx(stop, abs=0.05)
    # It ended at the auto-stop (held 0.25 s), not when its 60 s were up, and says why.
    assert run.session["final_state"] == "stopped"
    assert run.rows[-1][0] < run.rows[first_stop][0] + 0.5
    assert "REACHED" in panel.auto_stop_label.text()
    assert "2.00 mm margin of 'left mandibular canal'" in panel.auto_stop_label.text()
    assert panel.message.text().startswith(
        f"session ended at the auto-stop: the drill went {run.session['max_drill_mm']:.2f} mm"
    )
    # the engineering account in the tooltip, not on the screen
    assert "samples" not in panel.message.text() and "overruns" not in panel.message.text()
    tip = panel.message.toolTip()
    assert f"{run.session['samples']} samples" in tip and "assessment: score" in tip
    assert "0 fault event(s)" in tip or run.session["faults"]
    assert panel.last is not None and panel.state_label.text() == STATE_WORDS[panel.last.state]
    assert panel.state_label.toolTip() == f"device state: {panel.last.state}"
    assert panel.export_button.isEnabled() and not window.doc.rehearsing
    assert float(panel.depth_label.text().split()[1]) == pytest.approx(drill[-1], abs=0.01)
    # The forces kept apart on the gauge (hand, cutting, wall), in plain words on the screen,
    # the engineering terms in the tooltip; the time to the stop.
    assert panel.forces.forces["wall"] > 0.0 and panel.forces.forces["cutting"] == 0.0
    assert panel.forces.forces["hand"] == pytest.approx(run.last_armed.hand_n, abs=1e-9)
    assert panel.status_label.text().startswith("At the stop: the drill goes no deeper")
    assert "S0" not in panel.status_label.text() and "S0 =" in panel.status_label.toolTip()
    assert "past the stopped drill" in panel.status_label.toolTip()
    assert panel.timing_label.text().startswith("You reached the stop after")
    assert run.assessment is not None and run.assessment["breach"] is False
    window.tabs.setCurrentWidget(panel)
    window.grab().save(str(tmp_path / "rehearsal-stopped.png"))

    files = panel.export(tmp_path / "out")
    names = {p.relative_to(tmp_path / "out").as_posix() for p in files}
    assert {"force.csv", "profile.csv", "summary.json", "force.png"} <= names
    assert {"session/session.csv", "session/summary.json"} <= names
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["stop_depth_mm"] == pytest.approx(stop, abs=1e-4)  # written to 4 decimals
    # the one rehearsal summary builder: the same keys as `ctdrill rehearse`
    session = json.loads((tmp_path / "out" / "session" / "summary.json").read_text())
    assert session["calibration_illustrative"] is run.result.calibration.illustrative
    assert session["complete"] is True and session["reason"] is None
    assert {"max_safe_depth_mm", "profile_steps", "warnings"} <= set(session)
    with (tmp_path / "out" / "session" / "session.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(run.rows)
    assert max(float(r["drill_mm"]) for r in rows) == pytest.approx(drill.max(), abs=1e-4)


def test_a_push_too_weak_to_cut_says_so(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    panel.realtime = True  # paced: the readouts see the drill holding
    panel.duration_s = 3.0
    panel.hand.set_push(2.0)
    panel.device.setCurrentText(SIMULATOR)
    assert panel.run is None
    window.tabs.setCurrentWidget(panel)
    # predicted before it runs: the demo's crest holds 2 N at 0.4 mm; its cortex needs 9 N
    assert panel.timing_label.text().startswith("2 N is too weak: the drill stops at 0.")
    # the cortex's S0 peaks at 8.13 N: 10 N beats it by more than the master's 1 N friction
    assert "10 N reaches the stop (8.0 N more)" in panel.timing_label.text()
    with qtbot.waitSignal(panel.finished, timeout=60_000):
        panel.start()
        qtbot.waitUntil(lambda: "Push harder" in panel.status_label.text(), timeout=30_000)
        # "Push harder: 3 N needed to cut here, 1.0 N more than your 2.0 N."
        text = panel.status_label.text()
        assert "N needed to cut here" in text and "more than your 2.0 N" in text
        assert panel.forces.forces["cutting"] > 0.0 and panel.hand.need_n is not None
        qtbot.wait(200)  # let the layout fit the new texts before the picture
        window.grab().save(str(tmp_path / "rehearsal-too-weak.png"))
    run = panel.run
    assert run is not None and run.session is not None
    assert run.session["final_state"] == "cutting" and run.session["time_to_stop_s"] is None
    assert panel.timing_label.text() == "The drill did not reach the stop."


def test_stop_button_ends_a_realtime_run_in_the_safe_state(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    panel.hand.set_push(0.0)  # the hand rests: nothing moves
    panel.start()
    assert panel.run is not None
    # a hang guard: the session's process starts (spawn, imports) in a few seconds when idle,
    # beyond 10 s on 2 cores shared at load 12
    qtbot.waitUntil(lambda: panel.last is not None, timeout=60_000)
    # The plan is locked while the device holds its table: no edit reaches the document.
    plan = window.plan
    assert window.doc.rehearsing and not window.plan_panel.body.isEnabled()
    assert "locked" in window.plan_panel.lock_label.text()
    assert plan is not None
    window.slice_canvases["axial"].point_moved.emit("target", plan.target_lps + 1.0)
    assert window.plan is plan and "locked" in window.statusBar().currentMessage()
    assert not window.open_plan(phantom_case.plan_path) and window.plan is plan
    with qtbot.waitSignal(panel.finished, timeout=60_000):
        qtbot.mouseClick(panel.stop_button, Qt.MouseButton.LeftButton)
    assert panel.run.cancelled
    assert panel.run.record is not None and panel.run.record["outcome"] == "cancelled"
    assert panel.run.record["faults"][-1]["stop_acknowledged"] is True
    # Every readout shows the state the device last reported (after STOP and DISARM).
    assert panel.last is not None
    last_state = panel.last.state
    assert last_state in ("safe", "idle")
    assert panel.state_label.text() == STATE_WORDS[last_state]
    assert panel.state_label.toolTip() == f"device state: {last_state}"
    assert panel.safe_label.text() == (
        "safe state: YES" if last_state == "safe" else "safe state: no"
    )
    assert "STOP and DISARM acknowledged" in panel.message.text()
    assert f"device state: {last_state}" in panel.message.text()
    assert panel.export_button.isEnabled()
    assert not window.doc.rehearsing and window.plan_panel.body.isEnabled()
    assert window.plan_panel.lock_label.text() == ""


def test_a_silent_serial_device_is_reported_and_the_panel_recovers(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    panel.device.addItem("serial:loop://")  # pyserial's loopback: our own bytes come back
    panel.device.setCurrentText("serial:loop://")
    with qtbot.waitSignal(panel.finished, timeout=30_000):
        panel.start()
    assert panel.run is not None and panel.run.session is None
    assert panel.message.text().startswith("error:")
    assert panel.connect_button.isEnabled() and not panel.stop_button.isEnabled()


@pytest.mark.timeout(240)
def test_rehearsal_over_a_serial_port_reaches_the_auto_stop(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    # The session ends at the auto-stop; 20 s is only the bound. 30 N cuts to the stop in
    # about 1 s of device time even when a busy machine makes the emulator's clock slip.
    panel.duration_s = 20.0
    panel.hand.set_push(30.0)

    def case(link: Path, _emulator: subprocess.Popen[str]) -> None:
        panel.device.addItem(f"serial:{link}")
        panel.device.setCurrentText(f"serial:{link}")
        with qtbot.waitSignal(panel.finished, timeout=60_000):
            panel.start()
        run = panel.run
        assert run is not None and run.session is not None, None if run is None else run.error
        # the host process starved past the watchdog (a loaded machine): a fresh run
        reason, gap = run.session["reason"] or "", run.session["max_heartbeat_gap_s"]
        if host_late("raised watchdog" in reason, gap):
            raise HostLate(f"{reason} (host heartbeat gap {gap * 1e3:.0f} ms)")
        assert run.error == ""
        stop = window.view.curves.stop_depth_mm if window.view is not None else np.nan
        drill = np.array([r[2] for r in run.rows])
        states = [r[4] for r in run.rows]
        assert "stopped" in states
        assert drill.max() == pytest.approx(stop, abs=0.05)
        assert run.session["tick_rate_hz"] > 1000.0
        assert run.session["final_state"] == "stopped"  # ended at the auto-stop, not at 20 s
        assert run.rows[-1][0] < run.rows[states.index("stopped")][0] + 0.5

    with_fresh_emulator(tmp_path, case)
