"""The rehearsal panel: choose a device (simulator or serial port), exam mode and sound, connect,
arm, drive the drill with your hand (the mouse and the keys: :mod:`ctdrill.app.gui.hand_control`),
and feel it on screen: the three forces, the depth against the stop and the safety zone, the
vibration as a moving trace (:mod:`ctdrill.app.gui.gauges`) and as sound
(:mod:`ctdrill.app.gui.sound`); then the session's debrief (the Debrief page).

The control loop owns the device (:class:`ctdrill.app.gui.rehearsal.RehearsalRun`, its own
process); this panel polls its telemetry with a QTimer and sends the hand's push. It observes
the document's path result (what it would rehearse, or why it cannot) and tells the document
when a rehearsal runs (the plan locks), where the drill is, and the debrief when it ends. The
screen speaks plain words (:mod:`ctdrill.app.gui.rehearsal_words`); the engineering terms are
in the tooltips and ``summary.json``.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from PySide6.QtCore import QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QFrame,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLayout,
    QLineEdit,
    QPushButton,
    QScrollArea,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.errors import AppInputError
from ctdrill.app.exercise.trials import TrialCard, check_session_plan
from ctdrill.app.gui.debrief import Debrief, debrief_of
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.exercise_controls import ExerciseControls
from ctdrill.app.gui.rehearsal import RehearsalRun, Telemetry
from ctdrill.app.gui.rehearsal_choice import (
    SIMULATOR,
    device_choices,
    exam_settable,
    session_exam,
)
from ctdrill.app.gui.rehearsal_live import WARN_STYLE, LiveReadouts
from ctdrill.app.gui.rehearsal_words import (
    IGTL_TIP,
    SOUND_TIP,
    ended_texts,
    predicted_words,
    stop_why,
    timing_text,
)
from ctdrill.app.gui.results import PathView, block_reason, stop_explanation
from ctdrill.app.gui.sound import VibrationSound
from ctdrill.app.gui.workers import Runner
from ctdrill.app.igtl.frames import SLICER_PORT, parse_target
from ctdrill.app.trainee.exam import plan_hash
from ctdrill.engine.path import PathResult
from ctdrill.haptics.profile_table import ProfileTable

#: Telemetry poll period, ms (30 Hz display).
POLL_MS = 33
#: Shortest interval between 3D drill updates, s (a software-GL frame costs ~80 ms).
MIN_3D_UPDATE_S = 0.1


class RehearsalPanel(QWidget):
    """Device, exam mode and sound; the hand; the live gauges; the session's end."""

    finished = Signal()  # the run ended (auto-stop, Stop, retracted, an error or time is up)

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.result: PathResult | None = None
        self.blocked: str | None = "no CT series loaded"
        self.run: RehearsalRun | None = None
        self.last: Telemetry | None = None
        #: Session length, s (it ends earlier at the auto-stop or once retracted), and pacing
        #: of the simulator to the wall clock.
        self.duration_s = 120.0
        self.realtime = True
        self.sound = VibrationSound()
        self._last_emit = (-1.0, float("nan"))  # (monotonic s, depth mm) of the last update
        self._reported: RehearsalRun | None = None  # the run whose end was reported
        self._ending: RehearsalRun | None = None  # the run whose end is being reported
        self.debrief_runner = Runner(self._report_end, self._debrief_failed, parent=self)
        content = QWidget()
        outer = QVBoxLayout(content)
        outer.setSizeConstraint(QLayout.SizeConstraint.SetMinimumSize)  # scroll, never squeeze
        scroll = QScrollArea()  # whatever the screen's height, nothing overlaps
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QFrame.Shape.NoFrame)
        scroll.setWidget(content)
        frame = QVBoxLayout(self)
        frame.setContentsMargins(0, 0, 0, 0)
        frame.addWidget(scroll)

        dev = QGroupBox("Device")
        form = QFormLayout(dev)
        self.device = QComboBox()
        self.device.currentTextChanged.connect(lambda _t: self._update_buttons())
        self.refresh = QPushButton("Refresh")
        self.refresh.clicked.connect(self.refresh_devices)
        row = QHBoxLayout()
        row.addWidget(self.device, 1)
        row.addWidget(self.refresh)
        form.addRow("device", row)
        self.exam = QCheckBox("exam: no wall at the safety zone")
        self.exam.setToolTip(
            "Simulator only. The stop is not at the margin but 10 mm past the planned depth: "
            "you must stop yourself. The debrief records any breach (summary.json exam)."
        )
        form.addRow(self.exam)
        self.exercise = ExerciseControls(self)  # blind trials, aid levels
        form.addRow("exercise", self.exercise.picker)
        self.sound_box = QCheckBox("hear the vibration")
        self.sound_box.setToolTip(SOUND_TIP)
        self.sound_box.setChecked(True)
        self.sound_box.toggled.connect(self._sound_toggled)
        form.addRow(self.sound_box)
        self.record = QCheckBox("record the session")
        self.record.setChecked(True)
        form.addRow(self.record)
        self.igtl = QLineEdit()
        self.igtl.setPlaceholderText(f"off (e.g. localhost:{SLICER_PORT})")
        self.igtl.setToolTip(IGTL_TIP)
        form.addRow("stream to Slicer", self.igtl)
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

        self.live = LiveReadouts()
        self.state_label = self.live.state_label
        self.hand = self.live.hand
        self.depth_gauge = self.live.depth_gauge
        self.forces = self.live.forces
        self.status_label = self.live.status_label
        self.depth_label = self.live.depth_label
        self.clearance_label = self.live.clearance_label
        self.auto_stop_label = self.live.auto_stop_label
        self.safe_label = self.live.safe_label
        self.hand.push_changed.connect(self._push_changed)
        self.hand.retract_requested.connect(self._retract)
        outer.addWidget(self.live)
        outer.addWidget(self.exercise.answer_box)  # a blind trial's: name the bone
        self.timing_label = QLabel("-")
        self.timing_label.setWordWrap(True)
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
            if self.sound_box.isChecked():
                self.sound.prepare()  # a rehearsal may start: its audio library, loaded aside
            self.auto_stop_label.setText(f"auto-stop: at {stop_explanation(result)}")
            self._show_path(result)
            self._predict()

    def _show_path(self, path: PathResult, stop_mm: float | None = None) -> None:
        """The depth gauge: ``path``'s clearance (the exam's reaches past the plan) and margin,
        the plan's depth and the device's stop."""
        has = path.clearance_mm.shape[1] > 0
        planned = path.planned_depth_mm if self.result is None else self.result.planned_depth_mm
        self.depth_gauge.set_path(
            path.depth_mm,
            path.min_clearance_per_depth_mm if has else path.depth_mm[:0],
            margin_mm=path.binding_margin_mm,
            planned_mm=planned,
            stop_mm=path.stop_depth_mm if stop_mm is None else stop_mm,
        )

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
        self.igtl.setEnabled(not running)
        self.update_exam_toggle()
        self.export_button.setEnabled(self.run is not None and not running)

    def update_exam_toggle(self) -> None:
        """Exam mode is settable unless a session runs or the aid level locks it on."""
        running = self.run is not None and self.run.running
        self.exam.setEnabled(exam_settable(running=running, locked=self.exercise.exam_locked))

    # ------------------------------------------------------------------ the hand
    def _push_changed(self, push_n: float) -> None:
        if self.run is not None and self.run.running:
            self.run.set_push(push_n)
        self._predict()

    def _retract(self) -> None:
        if self.run is not None and self.run.running:
            self.run.retract()
        self.timing_label.setText("Retracting: the drill comes back out of the hole.")

    def set_blind(self, card: TrialCard | None) -> None:
        """Drill a blind trial (``card``) or not (None): :mod:`ctdrill.app.gui.blind`."""
        self.exercise.set_blind(card)
        self._predict()

    def _predict(self) -> None:
        """What the hand's push does, before and while the drill cuts (the model's words)."""
        if (blind := self.exercise.prediction()) is not None:
            return self.timing_label.setText(blind)
        run = self.run
        table = run.table if run is not None else None
        if table is None:
            if self.result is None:
                return
            table = ProfileTable.from_profile(self.result.profile, self.result.stop_depth_mm)
        text, tip = predicted_words(table, self.hand.push_n)
        self.timing_label.setText(text)
        self.timing_label.setToolTip(tip)

    def _sound_toggled(self, on: bool) -> None:
        if not on:
            self.sound.stop()
        elif self.run is not None and self.run.running:
            self._start_sound()

    def _start_sound(self) -> None:
        why = self.sound.start()
        self.sound_box.setText(
            "hear the vibration" if why is None else "hear the vibration: no sound here"
        )
        self.sound_box.setToolTip(SOUND_TIP if why is None else f"{SOUND_TIP} ({why})")

    # ------------------------------------------------------------------ run
    def start(self) -> None:
        """Connect to the chosen device, upload the table, arm and start polling."""
        doc = self.ctx.doc
        if self.result is None or self.blocked or doc.volume is None or doc.plan is None:
            return
        device = self.device.currentText() or SIMULATOR
        try:
            igtl_text = self.igtl.text().strip()
            igtl = parse_target(igtl_text, option="stream to Slicer") if igtl_text else None
            exam = session_exam(
                doc.volume, doc.plan, self.result, device, exam=self.exam.isChecked()
            )
            if (card := self.exercise.card) is not None:  # the trial's plan, as written
                check_session_plan(card, plan_hash(self.result.plan), where="the plan")
            self.run = RehearsalRun.start(
                self.result,
                device=device,
                push_n=self.hand.push_n,
                record=self.record.isChecked(),
                duration_s=self.duration_s,
                realtime=self.realtime,
                series_uid=doc.volume.info.series_uid,
                end_at_stop=exam is None,
                exam=exam,
                live=True,
                igtl=igtl,
            )
            self.run.hu = doc.hu_uncertainty
            self.run.blind, self.run.aids = self.exercise.card, self.exercise.level
        except (AppInputError, ValueError, OSError) as exc:
            self.message.setText(f"error: {exc}")
            self.run = None
            self._update_buttons()
            return
        run = self.run
        self._show_path(self.result if exam is None else exam.path, run.table.stop_depth_mm)
        where = (
            exam.note
            if exam is not None
            else f"the device stops the drill at {stop_explanation(self.result)}"
        )
        streaming = "" if igtl is None else f"; streaming to OpenIGTLink {igtl.text}"
        self.message.setText(f"armed on {device}; {where}{streaming}")
        self.message.setToolTip("")
        self._predict()
        if self.sound_box.isChecked():
            self._start_sound()
        doc.set_rehearsing(True)
        self.live.reset()
        self.hand.setFocus()
        self.timer.start()
        self._update_buttons()

    def stop(self) -> None:
        """Stop the run (the device goes to its safe state)."""
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
            if not ended:  # what the student saw, and when (the reaction is timed from it)
                run.shown(tel.time_s)
        warning = run.igtl_warning
        if warning is not None and not self.message.text().endswith(warning):
            self.message.setText(f"{self.message.text()}\nwarning: {warning}")
        if ended and self._ending is not run:
            self._ended(run, tel)

    def _debrief_failed(self, exc: BaseException, _tb: str) -> None:
        self.ctx.status(f"error: the session's debrief could not be made: {exc}")
        if self._ending is not None:
            self._report_end((self._ending, self._ending.latest(), None))

    def end_reported(self) -> bool:
        """No run, or the last run's end was reported (its message and debrief shown)."""
        return self.run is None or self._reported is self.run

    def _ended(self, run: RehearsalRun, tel: Telemetry | None) -> None:
        """The run ended: its debrief (10-30 ms of Python) is made in a worker; the end is
        reported with it (:meth:`_report_end`, then ``finished``)."""
        self._ending = run  # the buttons as while it ran until then (no new run before it)
        self.timer.stop()
        self.sound.stop()
        self.debrief_runner.submit(lambda: (run, tel, debrief_of(run)))

    def _report_end(self, ended: tuple[RehearsalRun, Telemetry | None, Debrief | None]) -> None:
        run, tel, debrief = ended
        self._reported = run
        self._update_buttons()
        text, details = ended_texts(run, tel, debrief)
        self.message.setToolTip(details)
        self.message.setText(text)
        self.timing_label.setText(self.exercise.prediction() or timing_text(run))
        if run.session is not None and run.session.get("final_state") == "stopped":
            self.auto_stop_label.setText(f"auto-stop: REACHED: {stop_why(run, self.result)}")
            self.auto_stop_label.setStyleSheet(WARN_STYLE)
        self.ctx.doc.set_rehearsing(False)
        self._path_changed(self.ctx.doc.path)
        if debrief is not None:
            self.ctx.doc.set_debrief(debrief)
        self.finished.emit()

    def show_telemetry(self, tel: Telemetry) -> None:
        """Update the live readouts from one telemetry sample."""
        self.last = tel
        if self.run is None:
            return
        self.live.show_telemetry(self.run, tel, stop_why(self.run, self.result), self.sound)
        now = time.monotonic()
        last_t, last_depth = self._last_emit
        if now - last_t >= MIN_3D_UPDATE_S and tel.drill_mm != last_depth:
            self._last_emit = (now, tel.drill_mm)
            self.ctx.doc.set_live_depth(tel.drill_mm)

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
        """Stop any run, the poll timer and the sound (window closing)."""
        self.timer.stop()
        self.sound.stop()
        self.debrief_runner.cancel()
        if self.run is not None and self.run.running:
            self.run.stop()
            self.run.join(timeout_s=2.0)
