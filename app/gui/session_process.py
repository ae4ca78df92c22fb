"""The rehearsal control loop in a process of its own (no Qt in it).

The host side of a session sends a heartbeat every 10 ms block and the device trips its 50 ms
watchdog when one is late. In the window's process the UI thread holds the interpreter lock
for tens of milliseconds at a time (a software-GL frame, a plot redraw), which starved a
host-loop *thread* into the watchdog over a real serial link; so the loop runs here, in a
separate interpreter, and talks to the window through a queue:

- ``("rows", rows)`` every block: ``(time_s, master_mm, drill_mm, force_cmd_n, state)``,
  then ``("hand", force_est_n)``: the device's reading of the hand's force at the block's end;
- then exactly one of ``("done", summary)`` (``SessionResult.to_json()`` of a complete
  session), ``("fault", summary)`` (the host ended it on a device fault or its own error,
  after STOP and DISARM: ``summary["reason"]`` says which), ``("cancelled", summary)`` (the
  stop event was set: the device was sent STOP and DISARM) or ``("error", message)`` (before
  ARM: nothing was armed);
- with ``SessionJob.igtl``, ``("warning", line)`` once if the OpenIGTLink stream fails
  (:mod:`ctdrill.app.igtl`) and, before the end, ``("igtl", report)`` (``summary.json``
  ``igtl``);
- before that, ``("state", name)``: the state the device reports once the session disarmed
  it (the window's readouts show it), and ``("assessment", fields)``: the session's
  assessment (:class:`ctdrill.haptics.assessment.Assessment`), when it was armed.

With a live hand (``SessionJob.live``) the window sets the push and the retraction in two
shared values the hand reads every block (:class:`ctdrill.haptics.hands.LiveHand`); a live
session also ends once the hand has drawn the drill back out of the hole it drilled.
"""

from __future__ import annotations

import contextlib
import time
import traceback
from dataclasses import dataclass
from typing import Any, Protocol

from ctdrill.app.igtl.frames import StreamSetup
from ctdrill.app.rehearse import open_device
from ctdrill.app.session_run import (
    AssessmentObserver,
    RehearsalSession,
    SessionObserver,
    StreamObserver,
)
from ctdrill.haptics.assessment import AssessmentContext, Assessor
from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.hands import RETRACTED_MM, Hand, LiveHand
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.session import STATE_NAMES, Row, parse_operator
from ctdrill.haptics.spec import DeviceSpec

#: With ``end_at_stop``, how long the device holds its auto-stop before the session ends, s.
AUTO_STOP_HOLD_S = 0.25


class _Queue(Protocol):
    def put(self, item: Any) -> None: ...


class _Event(Protocol):
    def is_set(self) -> bool: ...

    def wait(self, timeout: float | None = None) -> bool: ...


class _Shared(Protocol):
    value: Any


@dataclass(frozen=True)
class SessionJob:
    """What the control-loop process runs.

    Attributes
    ----------
    table : the force table to upload (with the stop depth the device enforces).
    operator_spec : ``push:N`` (``ctdrill.haptics.session.parse_operator``).
    device : the device (a simulator ``paced`` to the wall clock runs in real time).
    duration_s : session length, s.
    end_at_stop : end the session (complete, disarmed) once the device has held its auto-stop
        for ``AUTO_STOP_HOLD_S``: the drill can go no deeper, the window offers the export.
    igtl : stream the session to an OpenIGTLink server (None: no streaming).
    """

    table: ProfileTable
    operator_spec: str
    device: DeviceSpec
    duration_s: float
    end_at_stop: bool = False
    context: AssessmentContext | None = None
    live: bool = False
    igtl: StreamSetup | None = None


class WindowObserver:
    """The window's record of a session: its rows and hand readings on the queue ``out``; it
    ends the session (:attr:`done`) once the device held its auto-stop for
    :data:`AUTO_STOP_HOLD_S` (``job.end_at_stop``) or the live hand drew the drill back out of
    the hole it drilled (``retract`` set), and keeps a simulator to the wall clock."""

    def __init__(self, job: SessionJob, out: _Queue, stop: _Event, retract: _Shared | None) -> None:
        self.job, self.out, self.stop, self.retract = job, out, stop, retract
        self.wall0 = time.monotonic()
        self.stopped_at: float | None = None  # session time of the first auto-stop row
        self.drilled_mm = 0.0
        self.done = False

    def rows(self, rows: list[Row]) -> None:
        self.out.put(("rows", rows))
        self.out.put(("sent", time.monotonic()))  # when (the window's display lag is from it)
        if self.stopped_at is None:
            self.stopped_at = next((r[0] for r in rows if r[4] == "stopped"), None)
        held = self.stopped_at is not None and rows[-1][0] - self.stopped_at >= AUTO_STOP_HOLD_S
        self.drilled_mm = max(self.drilled_mm, max(r[2] for r in rows))
        out_again = (
            self.retract is not None
            and bool(self.retract.value)
            and self.drilled_mm > 0.0
            and rows[-1][1] <= RETRACTED_MM
        )  # the live hand drew the drill back out of the hole it drilled
        self.done = (self.job.end_at_stop and held) or out_again
        if self.job.device.host_paces:  # the simulator's time only advances in wait()
            ahead = rows[-1][0] - (time.monotonic() - self.wall0)
            if ahead > 0:
                self.stop.wait(ahead)

    def samples(self, block: list[TelemetrySample]) -> None:
        self.out.put(("hand", block[-1].force_est_n))

    def close(self) -> dict[str, Any]:
        return {}


def run_job(
    job: SessionJob,
    out: _Queue,
    stop: _Event,
    push: _Shared | None = None,
    retract: _Shared | None = None,
) -> None:
    """Entry point of the control-loop process: run ``job``, report on ``out``; ``push`` and
    ``retract`` are the live hand's shared values (``job.live``)."""
    try:
        operator = parse_operator(job.operator_spec)
        device = open_device(job.device)
    except (ValueError, OSError) as exc:
        out.put(("error", str(exc) or type(exc).__name__))
        return
    hand: Hand | None = None
    if job.live and push is not None and retract is not None:
        hand = LiveHand(lambda: float(push.value), lambda: bool(retract.value))
    window = WindowObserver(job, out, stop, retract if hand is not None else None)
    observers: list[SessionObserver] = [window]
    if job.context is not None:
        observers.append(AssessmentObserver(Assessor(job.context, job.table), if_armed=True))
    if job.igtl is not None:
        from ctdrill.app.igtl.stream import IgtlStream

        stream = IgtlStream(
            job.igtl.target, job.igtl.geometry, on_warning=lambda m: out.put(("warning", m))
        )
        observers.append(StreamObserver(stream))
    session = RehearsalSession(
        lambda: device,
        job.table,
        operator,
        job.duration_s,
        observers,
        hand=hand,
        should_stop=stop.is_set,
        until=lambda: window.done,
    )
    try:
        result, records = session.run(device)
        kind = {"complete": "done", "cancelled": "cancelled"}.get(result.outcome, "fault")
        with contextlib.suppress(ValueError, OSError):  # a lost link reports nothing more
            device.wait(0.05)
            states = [s.state for s in device.poll()]
            if states:  # after the session's DISARM (or STOP and DISARM), as reported
                out.put(("state", STATE_NAMES.get(states[-1], "?")))
        for key in ("assessment", "igtl"):
            if key in records:
                out.put((key, records[key]))
        out.put((kind, result.to_json()))
    except (ValueError, OSError) as exc:  # before ARM: a device that does not answer
        out.put(("error", str(exc) or type(exc).__name__))
    except Exception as exc:  # a bug (the device was made safe first): say so
        traceback.print_exc()
        out.put(("error", f"internal error: {exc!r}"))
    finally:
        device.close()
