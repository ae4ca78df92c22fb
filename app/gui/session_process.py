"""The rehearsal control loop in a process of its own (no Qt in it).

The host side of a session sends a heartbeat every 10 ms block and the device trips its 50 ms
watchdog when one is late. In the window's process the UI thread holds the interpreter lock
for tens of milliseconds at a time (a software-GL frame, a plot redraw), which starved a
host-loop *thread* into the watchdog over a real serial link; so the loop runs here, in a
separate interpreter, and talks to the window through a queue:

- ``("rows", rows)`` every block: ``(time_s, master_mm, drill_mm, force_cmd_n, state)``;
- then exactly one of ``("done", summary)`` (``SessionResult.to_json()``),
  ``("cancelled", "")`` (the stop event was set: the device was sent its emergency stop) or
  ``("error", message)``.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass
from typing import Any, Protocol

from ctdrill.app.rehearse import open_device
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.session import Row, parse_operator, run_session


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
    """

    table: ProfileTable
    operator_spec: str
    device_spec: str
    duration_s: float
    realtime: bool


class _Cancelled(Exception):
    """Raised from the sink to end a session the user stopped."""


def run_job(job: SessionJob, out: _Queue, stop: _Event) -> None:
    """Entry point of the control-loop process: run ``job``, report on ``out``."""
    try:
        operator = parse_operator(job.operator_spec)
        device = open_device(job.device_spec)
    except (ValueError, OSError) as exc:
        out.put(("error", str(exc) or type(exc).__name__))
        return
    wall0 = time.monotonic()

    def sink(rows: list[Row]) -> None:
        if stop.is_set():
            raise _Cancelled
        out.put(("rows", rows))
        if job.realtime:  # the simulator's time only advances in wait(): keep it to the clock
            ahead = rows[-1][0] - (time.monotonic() - wall0)
            if ahead > 0:
                stop.wait(ahead)

    try:
        result = run_session(device, job.table, operator, job.duration_s, sink=sink)
        out.put(("done", result.to_json()))
    except _Cancelled:
        try:
            device.stop()
            out.put(("cancelled", ""))
        except (ValueError, OSError) as exc:
            out.put(("error", f"emergency stop not acknowledged: {exc}"))
    except (ValueError, OSError) as exc:  # a device that does not answer, a lost port
        out.put(("error", str(exc) or type(exc).__name__))
    except Exception as exc:  # a bug: say so, keep the traceback on stderr
        traceback.print_exc()
        out.put(("error", f"internal error: {exc!r}"))
    finally:
        device.close()
