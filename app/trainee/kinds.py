"""How a recorded session ran: who drove it, on what, in which mode, and how it ended.

The trainee record stores these with every session (:mod:`ctdrill.app.trainee.record`); curves,
percentiles and grades leave out the sessions a device or its link ended
(:attr:`SessionKind.device_fault`), and count the ones the trainee ended (the drill past the
stop) or finished.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

#: Who drove a session: the window's hand (mouse, keys), a person on the robot (a hardware
#: device or its emulator on a serial line), or a script (``push``, ``feed``, ``script``,
#: ``human`` operators on the simulator).
OPERATOR_KINDS = ("hand", "robot", "scripted")
#: The modes that are not an exercise's name.
GUARDED, EXAM = "guarded", "exam"
#: The window's live hand, as ``summary.json`` ``operator`` names it.
WINDOW_OPERATOR = "live hand (the window)"
#: Reasons (``summary.json`` ``reason``: ``kind: message``) that the device or its link caused:
#: a watchdog, a reset, a lost link, silence, a report the host cannot trust, a host error.
DEVICE_FAULT_KINDS = frozenset(
    {"device_fault", "device_reset", "telemetry_silent", "device_clock", "host_error"}
)
#: ... and the one the trainee caused (it counts, as a breach does).
TRAINEE_FAULT_KINDS = frozenset({"drill_past_stop"})


@dataclass(frozen=True)
class SessionKind:
    """The record's columns of how a session ran (:func:`session_kind`)."""

    operator_kind: str | None
    device_kind: str | None
    mode: str
    complete: bool | None
    outcome: str | None
    reason: str | None
    device_fault: bool

    def columns(self) -> dict[str, Any]:
        """The ``sessions`` columns (booleans as 0/1, unknown as None)."""
        out = asdict(self)
        for name in ("complete", "device_fault"):
            if out[name] is not None:
                out[name] = int(out[name])
        return out


def operator_kind_of(operator: object, device: object) -> str | None:
    """``hand`` (the window's live hand), ``robot`` (any other operator on a serial device: a
    person's hand on the master) or ``scripted``; None when the summary does not say."""
    if not isinstance(operator, str):
        return None
    if operator == WINDOW_OPERATOR:
        return "hand"
    if isinstance(device, str) and device.startswith("serial:"):
        return "robot"
    return "scripted"


def device_kind_of(device: object) -> str | None:
    """``sim`` or ``serial`` (the port is not kept), or the spec's kind."""
    if not isinstance(device, str) or not device:
        return None
    return device.partition(":")[0]


def mode_of(summary: Mapping[str, Any]) -> str:
    """An exercise's name (a blind trial's card, ``summary.json`` ``exercise``; or
    ``summary.json`` ``mode``), ``exam`` (no wall at the margin), or ``guarded``."""
    card = summary.get("exercise")
    if isinstance(card, Mapping) and isinstance(card.get("exercise"), str) and card["exercise"]:
        return str(card["exercise"])
    mode = summary.get("mode")
    if isinstance(mode, str) and mode.strip():
        return mode.strip()
    exam = summary.get("exam")
    return EXAM if isinstance(exam, Mapping) and exam.get("enabled") else GUARDED


def device_fault_of(summary: Mapping[str, Any]) -> bool:
    """True when the session ended on a fault of the device or its link (not the trainee's):
    ``outcome`` ``fault`` for any reason but the trainee's (:data:`TRAINEE_FAULT_KINDS`):
    :data:`DEVICE_FAULT_KINDS` and any other the host may name."""
    if summary.get("outcome") != "fault":
        return False
    kind = str(summary.get("reason") or "").partition(":")[0].strip()
    return kind not in TRAINEE_FAULT_KINDS


def session_kind(summary: Mapping[str, Any]) -> SessionKind:
    """How the session of ``summary`` (its ``summary.json``) ran."""
    operator_kind = summary.get("operator_kind")
    if operator_kind not in OPERATOR_KINDS:
        operator_kind = operator_kind_of(summary.get("operator"), summary.get("device"))
    complete = summary.get("complete")
    outcome = summary.get("outcome")
    reason = summary.get("reason")
    return SessionKind(
        operator_kind=operator_kind,
        device_kind=device_kind_of(summary.get("device")),
        mode=mode_of(summary),
        complete=complete if isinstance(complete, bool) else None,
        outcome=outcome if isinstance(outcome, str) else None,
        reason=reason if isinstance(reason, str) else None,
        device_fault=device_fault_of(summary),
    )
