"""Rehearsal runs for the window, headless: device choice, a run that owns the device in its own
thread, telemetry the GUI polls, and the clearance at the live drill depth."""

from __future__ import annotations

import json
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from serial.tools import list_ports

from app.export import DEFAULT_RATE_HZ, ExportJob, write_exports
from app.pipeline import PathResult
from app.rehearse import open_device
from haptics.device import Device
from haptics.profile_table import ProfileTable
from haptics.session import Operator, Row, SessionCsv, SessionResult, parse_operator, run_session

#: The device-choice label of the simulator.
SIMULATOR = "simulator"


def device_choices() -> list[str]:
    """The simulator, then every serial port present (``serial:<device>``)."""
    ports = sorted(p.device for p in list_ports.comports())
    return [SIMULATOR, *(f"serial:{p}" for p in ports)]


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


class _Cancelled(Exception):
    """Raised from the session's sink to end a run the user stopped."""


class RehearsalRun:
    """One rehearsal on a device, run by ``haptics.session.run_session`` in its own thread.

    The thread owns the device; the GUI reads :meth:`latest` (thread-safe) and may call
    :meth:`stop`, which ends the session at the next 10 ms block with an emergency stop (the
    device latches its safe state). With ``realtime`` the simulator is paced to the wall clock
    (it would otherwise run as fast as the CPU allows).
    """

    def __init__(
        self,
        result: PathResult,
        device: Device,
        device_spec: str,
        operator: Operator,
        *,
        duration_s: float,
        realtime: bool,
        record: bool,
        series_uid: str,
    ) -> None:
        self.result = result
        self.device_spec = device_spec
        self.operator = operator
        self.duration_s = duration_s
        self.series_uid = series_uid
        self.table = ProfileTable.from_profile(result.profile, result.stop_depth_mm)
        self.rows: list[Row] = []
        self.session: SessionResult | None = None
        self.error = ""
        self.cancelled = False
        self._device = device
        self._realtime = realtime
        self._record = record
        self._lock = threading.Lock()
        self._latest: Telemetry | None = None
        self._stop = threading.Event()
        self._running = True
        self._thread = threading.Thread(target=self._run, name="ctdrill-rehearsal", daemon=True)

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
    ) -> RehearsalRun:
        """Open ``device`` (``simulator`` or ``serial:PORT``), then upload, arm and run in the
        background with a simulated hand pushing ``push_n`` newtons (simulator only)."""
        operator = parse_operator(f"push:{push_n:g}")
        dev = open_device("sim" if device == SIMULATOR else device)
        run = cls(
            result,
            dev,
            device,
            operator,
            duration_s=duration_s,
            realtime=realtime,
            record=record,
            series_uid=series_uid,
        )
        run._thread.start()
        return run

    @property
    def running(self) -> bool:
        """True until the session thread has finished."""
        return self._running

    def latest(self) -> Telemetry | None:
        """The newest telemetry sample (None before the first)."""
        with self._lock:
            return self._latest

    def stop(self) -> None:
        """Ask the session to end (emergency stop at the next block)."""
        self._stop.set()

    def join(self, timeout_s: float) -> None:
        """Wait for the session thread to end."""
        self._thread.join(timeout_s)

    def _sink(self, rows: list[Row], wall0: float) -> None:
        if self._stop.is_set():
            raise _Cancelled
        if self._record:
            self.rows.extend(rows)
        t, master, drill, force, state = rows[-1]
        tel = Telemetry(t, master, drill, force, state, clearance_at_mm(self.result, drill))
        with self._lock:
            self._latest = tel
        if self._realtime:
            ahead = t - (time.monotonic() - wall0)
            if ahead > 0:
                self._stop.wait(ahead)

    def _run(self) -> None:
        wall0 = time.monotonic()
        try:
            self.session = run_session(
                self._device,
                self.table,
                self.operator,
                self.duration_s,
                sink=lambda rows: self._sink(rows, wall0),
            )
        except _Cancelled:
            self.cancelled = True
            try:
                self._device.stop()
            except (ValueError, OSError) as exc:
                self.error = f"emergency stop not acknowledged: {exc}"
        except (ValueError, OSError) as exc:  # a device that does not answer, a lost port
            self.error = str(exc) or type(exc).__name__
        except Exception as exc:  # a bug: say so in the panel, keep the traceback on stderr
            self.error = f"internal error: {exc!r}"
            traceback.print_exc()
        finally:
            self._device.close()
            self._running = False

    def export(self, out_dir: Path) -> list[Path]:
        """Write the path export (``force.csv``, ``profile.csv``, ``summary.json``,
        ``force.png``, as ``ctdrill export``) and the recorded session (``session/session.csv``,
        ``session/summary.json``, as ``ctdrill rehearse``) into ``out_dir``."""
        written = write_exports(
            [ExportJob(self.result, "")],
            out_dir,
            feed_mm_s=None,
            rate_hz=DEFAULT_RATE_HZ,
            series_uid=self.series_uid,
        )
        session_dir = Path(out_dir) / "session"
        session_dir.mkdir(parents=True, exist_ok=True)
        csv_out = SessionCsv(session_dir / "session.csv")
        try:
            csv_out.write(self.rows)
        finally:
            csv_out.close()
        summary: dict[str, object] = {} if self.session is None else self.session.to_json()
        summary.update(
            {
                "stop_reason": self.result.stop_reason,
                "planned_depth_mm": float(self.result.planned_depth_mm),
                "calibration": self.result.calibration.name,
                "operator": self.operator.spec,
                "device": self.device_spec,
                "cancelled": self.cancelled,
                "recorded_rows": len(self.rows),
            }
        )
        (session_dir / "summary.json").write_text(
            json.dumps(summary, indent=2) + "\n", encoding="utf-8"
        )
        return [*written, session_dir / "session.csv", session_dir / "summary.json"]
