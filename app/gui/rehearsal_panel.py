"""The rehearsal panel: choose a device (simulator or serial port), connect, arm, watch the live
force / depth / clearance, see the auto-stop and the safe state, record and export.

The control loop owns the device (:class:`ctdrill.app.gui.rehearsal.RehearsalRun`, its own process);
this panel only polls its telemetry with a QTimer and sends commands. It observes the
document's path result (what it would rehearse, or why it cannot) and tells the document when a
rehearsal runs (the plan locks) and where the drill is. The session ends at the auto-stop; the
panel says why the drill stopped, and every readout shows the device's reported state.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from PySide6.QtCore import QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.rehearsal import SIMULATOR, RehearsalRun, Telemetry, device_choices
from ctdrill.app.gui.results import PathView, block_reason, stop_explanation
from ctdrill.app.pipeline import PathResult
from ctdrill.app.readout import live_readout, push_of, stop_timing
from ctdrill.haptics.predict import predict_push

#: Telemetry poll period, ms (30 Hz display).
POLL_MS = 33
#: Shortest interval between 3D drill updates, s (a software-GL frame costs ~80 ms).
MIN_3D_UPDATE_S = 0.1
#: The drill's feed readout is measured over this much session time, s.
FEED_WINDOW_S = 0.25

#: How the device force is named, by :attr:`ctdrill.app.readout.LiveReadout.kind`.
_FORCE_KIND = {
    "cutting": "cutting",
    "wall": "wall (stop)",
    "holding": "holding: push too weak to cut",
    "free": "no contact",
    "off": "off",
}

_STATE_STYLE = {
    "idle": "background:#505860; color:white",
    "cutting": "background:#2e7d32; color:white",
    "stopped": "background:#c62828; color:white",
    "safe": "background:#6a1b9a; color:white",
}


def _readout(text: str = "-") -> QLabel:
    label = QLabel(text)
    label.setStyleSheet("font-size:15pt; font-family:monospace")
    return label


def _pair(value: QLabel, note: QLabel) -> QWidget:
    """A big readout and a small note beside it."""
    box = QWidget()
    row = QHBoxLayout(box)
    row.setContentsMargins(0, 0, 0, 0)
    row.addWidget(value)
    row.addWidget(note, 1)
    return box


class RehearsalPanel(QWidget):
    """Device selection, arming and the live readouts."""

    finished = Signal()  # the run ended (auto-stop, Stop, an error or its time is up)

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.result: PathResult | None = None
        self.blocked: str | None = "no CT series loaded"
        self.run: RehearsalRun | None = None
        self.last: Telemetry | None = None
        #: Session length, s (the session ends earlier at the auto-stop), and pacing of the
        #: simulator to the wall clock.
        self.duration_s = 120.0
        self.realtime = True
        self._last_emit = (-1.0, float("nan"))  # (monotonic s, depth mm) of the last update
        self._reported: RehearsalRun | None = None  # the run whose end was reported
        self._drill_history: list[tuple[float, float]] = []  # (session s, drill mm)
        outer = QVBoxLayout(self)

        dev = QGroupBox("Device")
        form = QFormLayout(dev)
        self.device = QComboBox()
        self.refresh = QPushButton("Refresh")
        self.refresh.clicked.connect(self.refresh_devices)
        row = QHBoxLayout()
        row.addWidget(self.device, 1)
        row.addWidget(self.refresh)
        form.addRow("device", row)
        self.push = QDoubleSpinBox()
        self.push.setRange(0.0, 40.0)
        self.push.setValue(12.0)
        self.push.setSuffix(" N")
        self.push.setToolTip("Simulated surgeon: constant thrust on the master")
        form.addRow("simulated push", self.push)
        self.record = QCheckBox("record the session")
        self.record.setChecked(True)
        form.addRow(self.record)
        outer.addWidget(dev)

        buttons = QHBoxLayout()
        self.connect_button = QPushButton("Connect && arm")
        self.connect_button.clicked.connect(self.start)
        self.stop_button = QPushButton("Stop")
        self.stop_button.clicked.connect(self.stop)
        self.stop_button.setEnabled(False)
        buttons.addWidget(self.connect_button)
        buttons.addWidget(self.stop_button)
        outer.addLayout(buttons)

        live = QGroupBox("Live")
        live_box = QVBoxLayout(live)
        grid = QFormLayout()
        live_box.addLayout(grid)
        self.state_label = QLabel("idle")
        self.state_label.setStyleSheet(_STATE_STYLE["idle"])
        self.depth_label = _readout()
        self.hand_label = _readout()
        self.hand_label.setToolTip(
            "The operator's force: the device's reading (reaction-force observer); with the "
            "simulator also the push it was set to"
        )
        self.hand_note = QLabel("")
        self.force_label = _readout()
        self.force_label.setToolTip(
            "The force the device renders against the advance, named by what makes it: the "
            "cut, the stop's wall, or material holding a push too weak to cut"
        )
        self.force_kind_label = QLabel("-")
        self.force_kind_label.setWordWrap(True)
        self.force_kind_label.setStyleSheet("font-weight:bold")
        self.model_label = QLabel("-")
        self.model_label.setWordWrap(True)
        self.model_label.setToolTip(
            "The model's cutting force at the drill depth: S0, the static force a push must "
            "exceed to cut at all, and S0 (1 + Ke v) at the plan's feed (what export shows)"
        )
        self.status_label = QLabel("-")
        self.status_label.setWordWrap(True)
        self.timing_label = QLabel("time to the stop: -")
        self.timing_label.setWordWrap(True)
        self.clearance_label = _readout()
        self.auto_stop_label = QLabel("auto-stop: -")
        self.auto_stop_label.setWordWrap(True)
        self.safe_label = QLabel("safe state: -")
        grid.addRow("state", self.state_label)
        grid.addRow("drill depth", self.depth_label)
        grid.addRow("hand force", _pair(self.hand_label, self.hand_note))
        grid.addRow("device force", _pair(self.force_label, self.force_kind_label))
        grid.addRow("model here", self.model_label)
        grid.addRow("clearance", self.clearance_label)
        live_box.addWidget(self.status_label)
        live_box.addWidget(self.auto_stop_label)
        live_box.addWidget(self.safe_label)
        outer.addWidget(live)
        outer.addWidget(self.timing_label)

        self.export_button = QPushButton("Export session...")
        self.export_button.clicked.connect(self.export_dialog)
        self.export_button.setEnabled(False)
        outer.addWidget(self.export_button)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        outer.addWidget(self.message)
        outer.addStretch(1)

        self.timer = QTimer(self)
        self.timer.setInterval(POLL_MS)
        self.timer.timeout.connect(self.poll)
        self.refresh_devices()
        self._update_buttons()
        ctx.doc.path_changed.connect(self._path_changed)
        ctx.doc.plan_changed.connect(lambda _plan: self._path_changed(None))
        ctx.doc.volume_changed.connect(lambda _volume: self._path_changed(None))
        self._path_changed(None)

    # ------------------------------------------------------------------ case
    def _path_changed(self, view: PathView | None) -> None:
        doc = self.ctx.doc
        if self.run is not None and self.run.running:
            return  # the plan is locked: nothing changes under a running session
        result = view.result if view is not None and view.plan is doc.plan else None
        self.result = result
        self.set_blocked(block_reason(doc.volume, doc.plan, view, doc.path_error))
        if result is not None and not self.blocked and self.run is None:
            self.auto_stop_label.setText(f"auto-stop: at {stop_explanation(result)}")

    def refresh_devices(self) -> None:
        """List the simulator and the serial ports present now."""
        current = self.device.currentText()
        self.device.clear()
        self.device.addItems(device_choices())
        if current:
            self.device.setCurrentText(current)

    def set_blocked(self, reason: str | None) -> None:
        """Disable (reason) or enable arming."""
        self.blocked = reason
        if reason:
            self.message.setText(f"Rehearsal disabled: {reason}")
        elif self.run is None:
            self.message.setText("")
        self._update_buttons()

    def _update_buttons(self) -> None:
        running = self.run is not None and self.run.running
        self.connect_button.setEnabled(not running and not self.blocked and self.result is not None)
        self.stop_button.setEnabled(running)
        self.device.setEnabled(not running)
        self.export_button.setEnabled(self.run is not None and not running)

    # ------------------------------------------------------------------ run
    def start(self) -> None:
        """Connect to the chosen device, upload the profile, arm and start polling."""
        if self.result is None or self.blocked:
            return
        device = self.device.currentText() or SIMULATOR
        volume = self.ctx.doc.volume
        try:
            self.run = RehearsalRun.start(
                self.result,
                device=device,
                push_n=self.push.value(),
                record=self.record.isChecked(),
                duration_s=self.duration_s,
                realtime=self.realtime,
                series_uid="" if volume is None else volume.info.series_uid,
                end_at_stop=True,
            )
            self.run.hu = self.ctx.doc.hu_uncertainty
        except (ValueError, OSError) as exc:
            self.message.setText(f"error: {exc}")
            self.run = None
            self._update_buttons()
            return
        self.message.setText(
            f"armed on {device}; the device stops the drill at {stop_explanation(self.result)}"
        )
        self.timing_label.setText(f"time to the stop: {self._predicted_text(self.run)}")
        self.ctx.doc.set_rehearsing(True)
        self._drill_history.clear()
        self.timer.start()
        self._update_buttons()

    def stop(self) -> None:
        """Stop the run (the device goes to its stopped state)."""
        if self.run is not None:
            self.run.stop()
        self.poll()

    def poll(self) -> None:
        """Read the latest telemetry and update the readouts."""
        run = self.run
        if run is None:
            return
        ended = not run.running  # read first: once ended, latest() is the final sample
        tel = run.latest()
        if tel is not None:
            self.show_telemetry(tel)
        if ended and self._reported is not run:
            self._reported = run
            self.timer.stop()
            self._update_buttons()
            self.message.setText(end_message(run, tel))
            self.timing_label.setText(f"time to the stop: {timing_text(run)}")
            if run.session is not None and run.session.get("final_state") == "stopped":
                why = "" if self.result is None else stop_explanation(self.result)
                self.auto_stop_label.setText(f"auto-stop: REACHED: {why}")
                self.auto_stop_label.setStyleSheet("color:#c62828; font-weight:bold")
            self.ctx.doc.set_rehearsing(False)
            self._path_changed(self.ctx.doc.path)
            self.finished.emit()

    def show_telemetry(self, tel: Telemetry) -> None:
        """Update the live readouts from one telemetry sample."""
        self.last = tel
        self.state_label.setText(tel.state)
        self.state_label.setStyleSheet(_STATE_STYLE.get(tel.state, ""))
        self.depth_label.setText(f"{tel.drill_mm:6.2f} mm")
        self._show_forces(tel)
        clear = "-" if tel.clearance_mm is None else f"{tel.clearance_mm:6.2f} mm"
        self.clearance_label.setText(clear)
        why = "" if self.result is None else stop_explanation(self.result)
        reached = tel.state == "stopped"
        self.auto_stop_label.setText(f"auto-stop: {'REACHED' if reached else 'armed'}: {why}")
        self.auto_stop_label.setStyleSheet("color:#c62828; font-weight:bold" if reached else "")
        self.safe_label.setText("safe state: YES" if tel.state == "safe" else "safe state: no")
        now = time.monotonic()
        last_t, last_depth = self._last_emit
        if now - last_t >= MIN_3D_UPDATE_S and tel.drill_mm != last_depth:
            self._last_emit = (now, tel.drill_mm)
            self.ctx.doc.set_live_depth(tel.drill_mm)

    def _show_forces(self, tel: Telemetry) -> None:
        """Hand, device and model forces, and what the push does here (once the device is idle
        or safe again: its last armed reading, said so)."""
        run = self.run
        if run is None:
            return
        now_state = tel.state
        if now_state not in ("cutting", "stopped") and run.last_armed is not None:
            tel = run.last_armed
        push = push_of(run.operator_spec) if run.device_spec == SIMULATOR else None
        hist = self._drill_history
        if hist and tel.time_s < hist[-1][0]:
            hist.clear()  # a new run
        hist.append((tel.time_s, tel.drill_mm))
        while len(hist) > 2 and hist[1][0] <= tel.time_s - FEED_WINDOW_S:
            hist.pop(0)
        span = hist[-1][0] - hist[0][0]
        feed = (hist[-1][1] - hist[0][1]) / span if span >= 0.5 * FEED_WINDOW_S else None
        r = live_readout(
            run.table,
            state=tel.state,
            master_mm=tel.master_mm,
            drill_mm=tel.drill_mm,
            force_n=tel.force_n,
            hand_n=tel.hand_n,
            push_n=push,
            plan_feed_mm_s=run.result.plan.feed_mm_s,
            drill_feed_mm_s=feed,
        )
        self.hand_label.setText("-" if r.hand_n is None else f"{r.hand_n:6.2f} N")
        self.hand_note.setText("device reading" if push is None else f"(set {push:g} N)")
        self.force_label.setText(f"{tel.force_n:6.2f} N")
        kind = _FORCE_KIND[r.kind]
        status = r.status
        if tel.state != now_state:
            kind = f"{kind} (last armed; now {now_state})"
            status = f"{status} (last armed reading; the device is now {now_state}, no force)"
        self.force_kind_label.setText(kind)
        self.model_label.setText(
            f"S0 {r.s0_n:.2f} N static; {r.plan_force_n:.2f} N at the plan's "
            f"{run.result.plan.feed_mm_s:g} mm/s"
        )
        self.status_label.setText(status)
        weak = "color:#c62828; font-weight:bold"
        self.status_label.setStyleSheet(weak if r.kind == "holding" else "")

    @staticmethod
    def _predicted_text(run: RehearsalRun) -> str:
        push = push_of(run.operator_spec)
        if push is None:
            return "-"
        pred = predict_push(run.table, push)
        if pred.too_weak:
            return (
                f"never at {push:g} N: too weak to cut at {pred.stall_depth_mm:.2f} mm "
                f"(S0 = {pred.stall_s0_n:.2f} N)"
            )
        return f"the model's feed predicts {pred.time_to_stop_s:.2f} s at {push:g} N"

    def export_dialog(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Export the session to a folder")
        if path:
            self.export(path)

    def export(self, out_dir: str | os.PathLike[str]) -> list[Path]:
        """Write the recorded session with the same exporter as the CLI; returns the files."""
        if self.run is None:
            return []
        files = self.run.export(Path(out_dir))
        self.message.setText(f"exported {len(files)} file(s) to {out_dir}")
        return files

    def shutdown(self) -> None:
        """Stop any run and the poll timer (window closing)."""
        self.timer.stop()
        if self.run is not None and self.run.running:
            self.run.stop()
            self.run.join(timeout_s=2.0)


def end_message(run: RehearsalRun, last: Telemetry | None) -> str:
    """What the panel says when ``run`` ended, from what the device reported (``last``: the
    final telemetry sample, its state the device's own)."""
    state = "none reported" if last is None else last.state
    if run.error:
        return f"error: {run.error} (device state last reported: {state})"
    if run.cancelled:
        events = [] if run.record is None else run.record.get("faults", [])
        acked = bool(events) and all(
            events[-1].get(f"{step}_acknowledged") for step in ("stop", "disarm")
        )
        sent = "STOP and DISARM acknowledged" if acked else "STOP and DISARM not acknowledged"
        return f"stopped by the user: {sent}; device state: {state}"
    s = run.session
    if s is None:
        return f"session ended (device state: {state})"
    faults = len(s.get("faults", ()))
    reached = s.get("final_state") == "stopped"
    how = "at the auto-stop" if reached else "(its time is up)"
    return (
        f"session ended {how}: deepest drill {s['max_drill_mm']:.2f} mm of stop "
        f"{s['stop_depth_mm']:.2f} mm, {s['samples']} samples, {s['overruns']} overruns, "
        f"{faults} fault event(s); device state now: {state}. Export the session to keep it."
    )


def timing_text(run: RehearsalRun) -> str:
    """The time to the stop once ``run`` ended: the session's against the model's, and why
    they differ (push operators; "-" otherwise)."""
    push = push_of(run.operator_spec)
    record = run.record
    if push is None or record is None or run.cancelled or run.error:
        return "-" if push is None else RehearsalPanel._predicted_text(run)
    ended_s = run.rows[-1][0] if run.rows else run.duration_s
    return stop_timing(run.table, push, record.get("time_to_stop_s"), ended_s).message
