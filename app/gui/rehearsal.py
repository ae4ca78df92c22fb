"""Rehearsal runs for the window, headless: device choice, a run whose control loop owns the
device in its own process, telemetry the GUI polls, and the clearance at the live depth."""

from __future__ import annotations

import multiprocessing
import queue
import time
from collections import deque
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.app.exercise.aids import AidLevel
from ctdrill.app.exercise.trials import TrialCard, blind_summary, write_session_only
from ctdrill.app.export import write_exports
from ctdrill.app.gui.rehearsal_choice import SIMULATOR as SIMULATOR
from ctdrill.app.gui.rehearsal_choice import device_choices as device_choices
from ctdrill.app.gui.rehearsal_choice import device_of
from ctdrill.app.gui.rehearsal_choice import exam_settable as exam_settable
from ctdrill.app.gui.rehearsal_choice import session_exam as session_exam
from ctdrill.app.gui.session_process import SessionJob, run_job
from ctdrill.app.igtl.frames import IgtlTarget, StreamSetup
from ctdrill.app.readout import push_of
from ctdrill.app.session_csv import session_csv_text
from ctdrill.app.session_run import rehearsal_summary, summary_json
from ctdrill.app.trainee.exam import ExamSetup, assessment_context, plan_hash
from ctdrill.app.trainee.session_table import (
    DISPLAY_FILE,
    TABLE_FILE,
    display_csv,
    table_text,
    with_display,
)
from ctdrill.engine.case import ExportJob
from ctdrill.engine.path import PathResult
from ctdrill.engine.settings import DEFAULTS
from ctdrill.engine.summarize import CaseContext
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.session import Row
from ctdrill.model.band import HuUncertainty

#: Rows kept for the live vibration trace (0.5 s at the 1 kHz telemetry).
TRACE_ROWS = 500


def clearance_at_mm(result: PathResult, depth_mm: float) -> float | None:
    """Clearance to the nearest landmark with the tip at ``depth_mm`` (linear between the
    profile's depths, clamped to its ends), mm; None without landmarks."""
    if result.clearance_mm.shape[1] == 0:
        return None
    curve = result.min_clearance_per_depth_mm
    return float(np.interp(depth_mm, result.depth_mm, curve))


@dataclass(frozen=True)
class Telemetry:
    """One display sample of a run."""

    time_s: float
    master_mm: float
    drill_mm: float
    force_n: float
    state: str  # idle | cutting | stopped | safe
    clearance_mm: float | None
    hand_n: float | None = None  # the device's reading of the hand's force (RFOB)


class RehearsalRun:
    """One rehearsal, its control loop in a separate process
    (:mod:`ctdrill.app.gui.session_process`).

    The process owns the device; the window polls :meth:`latest` (which drains the process's
    queue) and may call :meth:`stop`, which ends the session at the next 10 ms block with an
    emergency stop (the device latches its safe state). With ``realtime`` the simulator is
    paced to the wall clock (it would otherwise run as fast as the CPU allows); a serial device
    runs on its own clock and is never paced. The process is started with ``spawn`` (no fork
    of a Qt process), so a script that starts runs needs the usual ``if __name__ ==
    "__main__":`` guard (``ctdrill gui`` and pytest have it).
    """

    def __init__(
        self,
        result: PathResult,
        device_spec: str,
        operator_spec: str,
        *,
        duration_s: float,
        realtime: bool,
        record: bool,
        series_uid: str,
        end_at_stop: bool = False,
        exam: ExamSetup | None = None,
        live: bool = False,
        igtl: IgtlTarget | None = None,
    ) -> None:
        self.result = result
        self.device_spec = device_spec
        #: The device the choice names.
        self.device = device_of(device_spec, realtime=realtime)
        self.operator_spec = operator_spec
        self.duration_s = duration_s
        self.series_uid = series_uid
        #: Exam mode's table and why its stop is where it is (None: the margin's wall).
        self.exam = exam
        #: The blind trial's card when the session drills one (its summary and export hide
        #: the bone: :func:`ctdrill.app.exercise.trials.blind_summary`).
        self.blind: TrialCard | None = None
        #: The stop-yourself exercise's level the session runs at (its summary says so).
        self.aids: AidLevel | None = None
        self.table = (
            ProfileTable.from_profile(result.profile, result.stop_depth_mm)
            if exam is None
            else exam.table
        )
        #: The hand is set while the session runs (:meth:`set_push`, :meth:`retract`).
        self.live = live
        self.rows: list[Row] = []
        #: What the window showed when (:meth:`shown`): ``(time_s of the sample shown,
        #: session time it was on screen)``, the session's ``display.csv``.
        self.display: list[tuple[float, float]] = []
        self._sent_at: float | None = None  # when the newest rows left the control loop
        #: The newest rows' ``(time_s, force_cmd_n)`` (the live vibration trace).
        self.trace: deque[tuple[float, float]] = deque(maxlen=TRACE_ROWS)
        #: The session's assessment (``Assessment.to_json()``) once it ended (None before).
        self.assessment: dict[str, Any] | None = None
        #: The session's ``summary.json``, frozen when first asked for after the end.
        self._summary: dict[str, Any] | None = None
        #: SessionResult.to_json() of a session that ran its course or ended on a fault.
        self.session: dict[str, Any] | None = None
        #: SessionResult.to_json() once the session ended in any way (also when cancelled);
        #: None if it never began (the device failed before ARM).
        self.record: dict[str, Any] | None = None
        self.error = ""
        self.cancelled = False
        #: The series' HU uncertainty for the summary's force band (the window's, if any).
        self.hu: HuUncertainty | None = None
        #: The OpenIGTLink stream's server, its warning once it failed, and its report
        #: (``summary.json`` ``igtl``) once the session ended.
        self.igtl_target = igtl
        self.igtl_warning: str | None = None
        self.igtl: dict[str, Any] | None = None
        self._record = record
        self._latest: Telemetry | None = None
        self._hand_n: float | None = None
        #: The newest sample while the device was armed (cutting or stopped).
        self.last_armed: Telemetry | None = None
        self._ended = False
        ctx = multiprocessing.get_context("spawn")  # no fork of a Qt process
        self._queue = ctx.Queue()
        self._stop = ctx.Event()
        push = push_of(operator_spec)
        self._push = ctx.Value("d", 0.0 if push is None else push)
        self._retract = ctx.Value("b", 0)
        #: What the session is assessed against (``table.json`` with the table).
        self.context = assessment_context(result, None if exam is None else exam.path)
        job = SessionJob(
            table=self.table,
            operator_spec=operator_spec,
            device=self.device,
            duration_s=duration_s,
            end_at_stop=end_at_stop,
            context=self.context,
            live=live,
            igtl=None if igtl is None else StreamSetup.of_plan(igtl, result.plan),
        )
        self._process = ctx.Process(
            target=run_job,
            args=(job, self._queue, self._stop, self._push, self._retract),
            name="ctdrill-session",
        )
        self._process.daemon = True

    @classmethod
    def start(
        cls,
        result: PathResult,
        *,
        device: str,
        push_n: float,
        record: bool,
        duration_s: float = 120.0,
        realtime: bool = True,
        series_uid: str = "",
        end_at_stop: bool = False,
        exam: ExamSetup | None = None,
        live: bool = False,
        igtl: IgtlTarget | None = None,
    ) -> RehearsalRun:
        """Start a session on ``device`` (``simulator`` or ``serial:PORT``): upload, arm and
        run, with a simulated hand pushing ``push_n`` newtons (simulator and emulator); with
        ``live`` the push follows :meth:`set_push` and :meth:`retract` while it runs; with
        ``end_at_stop`` the session ends once the device holds its auto-stop; with ``exam``
        the exam's table is uploaded instead of the margin's (on hardware its wall stands at
        the canal's surface, :func:`ctdrill.app.trainee.exam.exam_at_surface`); with ``igtl``
        the session streams to that OpenIGTLink server (docs/slicer.md)."""
        if not (np.isfinite(push_n) and push_n >= 0.0):
            raise ValueError(f"simulated push: give a force >= 0 N, got {push_n}")
        run = cls(
            result,
            device,
            f"push:{push_n:g}",
            duration_s=duration_s,
            realtime=realtime,
            record=record,
            series_uid=series_uid,
            end_at_stop=end_at_stop,
            exam=exam,
            live=live,
            igtl=igtl,
        )
        run._process.start()
        return run

    def set_push(self, push_n: float) -> None:
        """The hand's push from now on, N (a live run; clamped to 0..78 N by the device)."""
        self._retract.value = 0
        self._push.value = float(push_n)

    def retract(self) -> None:
        """Draw the handle back out of the hole (a live run), then rest."""
        self._push.value = 0.0
        self._retract.value = 1

    @property
    def push_n(self) -> float:
        """The push the hand is set to, N."""
        return float(self._push.value)

    @property
    def retracting(self) -> bool:
        """The hand is drawing the handle back."""
        return bool(self._retract.value)

    def _drain(self) -> None:
        """Take everything the control loop reported so far (UI thread)."""
        while True:
            try:
                kind, payload = self._queue.get_nowait()
            except queue.Empty:
                break
            if kind == "rows":
                rows: list[Row] = payload
                if self._record:
                    self.rows.extend(rows)
                self.trace.extend((r[0], r[3]) for r in rows)
                t, master, drill, force, state, _hand = rows[-1]
                exam = self.exam
                self._latest = Telemetry(
                    t,
                    master,
                    drill,
                    force,
                    state,
                    clearance_at_mm(self.result if exam is None else exam.path, drill),
                    self._hand_n,
                )
            elif kind == "hand":
                self._hand_n = float(payload)
                if self._latest is not None:
                    self._latest = replace(self._latest, hand_n=self._hand_n)
            if kind in ("rows", "hand") and self._latest is not None:
                if self._latest.state in ("cutting", "stopped"):
                    self.last_armed = self._latest
            elif kind == "state":  # the device's state once the session disarmed it
                if self._latest is not None:
                    self._latest = replace(self._latest, state=str(payload))
            elif kind == "sent":
                self._sent_at = float(payload)
            elif kind == "assessment":
                self.assessment = payload
            elif kind == "warning":
                self.igtl_warning = str(payload)
            elif kind == "igtl":
                self.igtl = payload
            else:
                self._ended = True
                self.assessment = self._assessed()
                if kind in ("done", "fault", "cancelled"):
                    self.record = payload
                if kind == "done":
                    self.session = payload
                elif kind == "cancelled":
                    self.cancelled = True
                elif kind == "fault":
                    self.session = payload
                    self.error = (
                        f"the session ended on a fault ({payload['reason']}); the device was "
                        "sent STOP and DISARM"
                    )
                else:
                    self.error = str(payload)
        if not self._ended and self._process.exitcode is not None:
            time.sleep(0.05)  # the queue's feeder may still be flushing the last message
            if self._queue.empty():
                self._ended = True
                self.error = (
                    f"the session process ended unexpectedly (exit code {self._process.exitcode})"
                )
            else:
                self._drain()

    @property
    def running(self) -> bool:
        """True until the control loop has reported its end."""
        self._drain()
        return not self._ended

    def latest(self) -> Telemetry | None:
        """The newest telemetry sample (None before the first)."""
        self._drain()
        return self._latest

    def stop(self) -> None:
        """Ask the session to end (emergency stop at the next block)."""
        self._stop.set()

    def join(self, timeout_s: float) -> None:
        """Wait for the control loop to end, then take its last reports."""
        end = time.monotonic() + timeout_s
        while self.running and time.monotonic() < end:
            time.sleep(0.01)
        self._process.join(max(0.0, end - time.monotonic()))
        if self._process.is_alive():
            self._process.terminate()

    def summary(self) -> dict[str, Any]:
        """The session's ``summary.json`` (as ``ctdrill rehearse`` writes it, with
        ``cancelled`` and ``recorded_rows``), made once after the session ended: the export and
        the trainee record get the same bytes."""
        if self._summary is not None and not self.running:
            return self._summary
        summary = rehearsal_summary(
            {} if self.record is None else self.record,
            self.result,
            self.table,
            operator="live hand (the window)" if self.live else self.operator_spec,
            device=self.device_spec,
            duration_s=self.duration_s,
            seed=0,
            context=self.case(),
            assessment=self.assessment,
            exam=self.exam,
        )
        summary.update({"cancelled": self.cancelled, "recorded_rows": len(self.rows)})
        if self.igtl is not None:
            summary["igtl"] = self.igtl
        if self.aids is not None:
            summary.update(self.aids.summary())
        if self.blind is not None:  # a blind trial: nothing that gives the bone away
            summary = blind_summary(summary, self.blind)
        if not self.running:
            self._summary = summary
        return summary

    def case(self) -> CaseContext:
        """What the window's export and the session's summary share (the same values)."""
        return CaseContext(settings=DEFAULTS, series_uid=self.series_uid, hu_uncertainty=self.hu)

    def shown(self, time_s: float) -> None:
        """The window has just drawn the newest sample, of session time ``time_s``: logged
        with the session time it was on screen, ``time_s`` plus the wall-clock time since the
        control loop handed it over (the queue's and the window's delay), once per new sample,
        while the session runs on a device that keeps to the wall clock."""
        if self._sent_at is None or not self.device.paced or self._ended:
            return
        if self.display and self.display[-1][0] >= time_s:
            return
        self.display.append((time_s, time_s + max(time.monotonic() - self._sent_at, 0.0)))

    def display_text(self) -> str | None:
        """``display.csv`` (None: the window logged nothing, e.g. an unpaced simulator)."""
        return display_csv(self.display)

    def _assessed(self) -> dict[str, Any] | None:
        """The session's assessment, with a display log recomputed from the recorded rows and
        it (:func:`~ctdrill.app.trainee.session_table.with_display`)."""
        if not self.rows or not self._record:
            return self.assessment
        rows = session_csv_text(self.rows)
        return with_display(self.assessment, rows, self.table, self.context, self.display)

    def session_files(self) -> tuple[str, str]:
        """``(summary.json, session.csv)`` texts of the ended session."""
        return summary_json(self.summary()), session_csv_text(self.rows)

    def table_text(self) -> str:
        """``table.json``: what the session is assessed against (``ctdrill assess``)."""
        blind = self.blind  # a blind trial's force table is sealed to it
        trial = None if blind is None else (blind.exercise_id, blind.trial)
        return table_text(self.table, self.context, plan_hash(self.result.plan), trial=trial)

    def export(self, out_dir: Path) -> list[Path]:
        """Write the path export (``force.csv``, ``profile.csv``, ``summary.json``,
        ``force.png``, as ``ctdrill export``) and the recorded session (``session/session.csv``,
        ``session/summary.json``, ``session/table.json``, as ``ctdrill rehearse``) into
        ``out_dir``, all in one swap (the folder is replaced whole or not at all); a blind
        trial's session alone."""
        summary_text, csv_text = self.session_files()
        display = self.display_text()
        if self.blind is not None:  # a blind trial: the session alone (no HU, no profile)
            files = {"summary.json": summary_text, "session.csv": csv_text}
            files[TABLE_FILE] = self.table_text()
            if display is not None:
                files[DISPLAY_FILE] = display
            return write_session_only(out_dir, files)
        return write_exports(
            [ExportJob(self.result, "")],
            out_dir,
            self.case(),
            extra_files={
                "session/session.csv": csv_text,
                "session/summary.json": summary_text,
                f"session/{TABLE_FILE}": self.table_text(),
            }
            | ({} if display is None else {f"session/{DISPLAY_FILE}": display}),
        )
