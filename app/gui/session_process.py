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
- before that, ``("state", name)``: the state the device reports once the session disarmed
  it (the window's readouts show it).
"""

from __future__ import annotations

import contextlib
import time
import traceback
from dataclasses import dataclass
from typing import Any, Protocol

from ctdrill.app.rehearse import open_device
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import STATE_NAMES, Row, parse_operator

#: With ``end_at_stop``, how long the device holds its auto-stop before the session ends, s.
AUTO_STOP_HOLD_S = 0.25


class _Queue(Protocol):
    def put(self, item: Any) -> None: ...


class _Event(Protocol):
    def is_set(self) -> bool: ...

    def wait(self, timeout: float | None = None) -> bool: ...


@dataclass(frozen=True)
class SessionJob:
    """What the control-loop process runs.

    Attributes
    ----------
    table : the force table to upload (with the stop depth the device enforces).
    operator_spec : ``push:N`` (``ctdrill.haptics.session.parse_operator``).
    device_spec : ``sim`` or ``serial:PORT`` (``ctdrill.app.rehearse.open_device``).
    duration_s : session length, s.
    realtime : pace the simulator to the wall clock (a real device is never paced).
    end_at_stop : end the session (complete, disarmed) once the device has held its auto-stop
        for ``AUTO_STOP_HOLD_S``: the drill can go no deeper, the window offers the export.
    """

    table: ProfileTable
    operator_spec: str
    device_spec: str
    duration_s: float
    realtime: bool
    end_at_stop: bool = False


def run_job(job: SessionJob, out: _Queue, stop: _Event) -> None:
    """Entry point of the control-loop process: run ``job``, report on ``out``."""
    try:
        operator = parse_operator(job.operator_spec)
        device = open_device(job.device_spec)
    except (ValueError, OSError) as exc:
        out.put(("error", str(exc) or type(exc).__name__))
        return
    wall0 = time.monotonic()
    stopped_at: list[float] = []  # session time of the first auto-stop row
    held = [False]

    def sink(rows: list[Row]) -> None:
        out.put(("rows", rows))
        if not stopped_at:
            stopped_at.extend(r[0] for r in rows if r[4] == "stopped")
        held[0] = bool(stopped_at) and rows[-1][0] - stopped_at[0] >= AUTO_STOP_HOLD_S
        if job.realtime:  # the simulator's time only advances in wait(): keep it to the clock
            ahead = rows[-1][0] - (time.monotonic() - wall0)
            if ahead > 0:
                stop.wait(ahead)

    try:
        result = run_session(
            device,
            job.table,
            operator,
            job.duration_s,
            sink=sink,
            should_stop=stop.is_set,
            until=(lambda: held[0]) if job.end_at_stop else None,
            on_samples=lambda samples: out.put(("hand", samples[-1].force_est_n)),
        )
        kind = {"complete": "done", "cancelled": "cancelled"}.get(result.outcome, "fault")
        with contextlib.suppress(ValueError, OSError):  # a lost link reports nothing more
            device.wait(0.05)
            states = [s.state for s in device.poll()]
            if states:  # after the session's DISARM (or STOP and DISARM), as reported
                out.put(("state", STATE_NAMES.get(states[-1], "?")))
        out.put((kind, result.to_json()))
    except (ValueError, OSError) as exc:  # before ARM: a device that does not answer
        out.put(("error", str(exc) or type(exc).__name__))
    except Exception as exc:  # a bug (the device was made safe first): say so
        traceback.print_exc()
        out.put(("error", f"internal error: {exc!r}"))
    finally:
        device.close()
