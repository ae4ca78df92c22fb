"""The rehearsal panel: choose a device (simulator or serial port), connect, arm, watch the live
force / depth / clearance, see the auto-stop and the safe state, record and export.

The control loop owns the device (:class:`ctdrill.app.gui.rehearsal.RehearsalRun`, its own process);
this panel only polls its telemetry with a QTimer and sends commands.
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

from ctdrill.app.gui.rehearsal import SIMULATOR, RehearsalRun, Telemetry, device_choices
from ctdrill.app.pipeline import PathResult
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.types import Plan

#: Telemetry poll period, ms (30 Hz display).
POLL_MS = 33
#: Shortest interval between 3D drill updates, s (a software-GL frame costs ~80 ms).
MIN_3D_UPDATE_S = 0.1

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


class RehearsalPanel(QWidget):
    """Device selection, arming and the live readouts."""

    depth_changed = Signal(float)  # drill depth from telemetry, mm
    finished = Signal()  # the run ended (stop, safe state or disconnect)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.volume: CTVolume | None = None
        self.plan: Plan | None = None
        self.result: PathResult | None = None
        self.blocked: str | None = "no CT series loaded"
        self.run: RehearsalRun | None = None
        self.last: Telemetry | None = None
        #: Session length, s, and pacing of the simulator to the wall clock.
        self.duration_s = 120.0
        self.realtime = True
        self._last_emit = (-1.0, float("nan"))
        self._reported: RehearsalRun | None = (
            None  # the run whose end was reported  # (monotonic s, depth mm) of the last 3D update
        )
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
        grid = QFormLayout(live)
        self.state_label = QLabel("idle")
        self.state_label.setStyleSheet(_STATE_STYLE["idle"])
        self.depth_label = _readout()
        self.force_label = _readout()
        self.clearance_label = _readout()
        self.auto_stop_label = QLabel("auto-stop: -")
        self.safe_label = QLabel("safe state: no")
        grid.addRow("state", self.state_label)
        grid.addRow("drill depth", self.depth_label)
        grid.addRow("force", self.force_label)
        grid.addRow("clearance", self.clearance_label)
        grid.addRow(self.auto_stop_label)
        grid.addRow(self.safe_label)
        outer.addWidget(live)

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

    # ------------------------------------------------------------------ case
    def refresh_devices(self) -> None:
        """List the simulator and the serial ports present now."""
        current = self.device.currentText()
        self.device.clear()
        self.device.addItems(device_choices())
        if current:
            self.device.setCurrentText(current)

    def set_case(
        self, volume: CTVolume | None, plan: Plan, result: PathResult, *, blocked: str | None
    ) -> None:
        """The case to rehearse (a new path result); ``blocked`` disables arming, with why."""
        self.volume, self.plan, self.result = volume, plan, result
        self.set_blocked(blocked)

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
        try:
            self.run = RehearsalRun.start(
                self.result,
                device=device,
                push_n=self.push.value(),
                record=self.record.isChecked(),
                duration_s=self.duration_s,
                realtime=self.realtime,
                series_uid="" if self.volume is None else self.volume.info.series_uid,
            )
        except (ValueError, OSError) as exc:
            self.message.setText(f"error: {exc}")
            self.run = None
            self._update_buttons()
            return
        self.message.setText(f"armed on {device}; stop depth {self.result.stop_depth_mm:.2f} mm")
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
            if run.error:
                self.message.setText(f"error: {run.error}")
            elif run.session is not None:
                s = run.session
                self.message.setText(
                    f"session ended ({s['final_state']}): deepest drill "
                    f"{s['max_drill_mm']:.2f} mm of stop {s['stop_depth_mm']:.2f} mm, "
                    f"{s['samples']} samples, {s['overruns']} overruns"
                )
            elif run.cancelled:
                self.message.setText("stopped by the user (device in its safe state)")
            self.finished.emit()

    def show_telemetry(self, tel: Telemetry) -> None:
        """Update the live readouts from one telemetry sample."""
        self.last = tel
        self.state_label.setText(tel.state)
        self.state_label.setStyleSheet(_STATE_STYLE.get(tel.state, ""))
        self.depth_label.setText(f"{tel.drill_mm:6.2f} mm")
        self.force_label.setText(f"{tel.force_n:6.2f} N")
        clear = "-" if tel.clearance_mm is None else f"{tel.clearance_mm:6.2f} mm"
        self.clearance_label.setText(clear)
        self.auto_stop_label.setText(
            "auto-stop: REACHED" if tel.state == "stopped" else "auto-stop: armed"
        )
        self.auto_stop_label.setStyleSheet(
            "color:#c62828; font-weight:bold" if tel.state == "stopped" else ""
        )
        self.safe_label.setText("safe state: YES" if tel.state == "safe" else "safe state: no")
        now = time.monotonic()
        last_t, last_depth = self._last_emit
        if now - last_t >= MIN_3D_UPDATE_S and tel.drill_mm != last_depth:
            self._last_emit = (now, tel.drill_mm)
            self.depth_changed.emit(tel.drill_mm)

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
