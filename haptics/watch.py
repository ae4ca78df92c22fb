"""The host's watch of a session's telemetry (docs/protocol.md section 5).

:class:`TelemetryWatch` finds the first reason to end an armed session: the drill reported
beyond the stop depth by more than :func:`stop_tolerance_mm`, a non-finite position, a fault
flag of :data:`ABORT_FLAGS`, a state other than cutting or stopped, a device that came back
without the session, or telemetry silent for more than :data:`SILENT_WATCHDOG_PERIODS`
watchdog periods. :func:`ctdrill.haptics.run.run_session` acts on it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.plant import ENCODER_M
from ctdrill.haptics.protocol import DeviceState, Fault
from ctdrill.haptics.session import STATE_NAMES

#: Telemetry silent for more than this many device watchdog periods ends the session.
SILENT_WATCHDOG_PERIODS = 2
#: Fault flags that end a session (the limits PEAK, THERMAL and TRAVEL are logged only).
ABORT_FLAGS = int(Fault.WATCHDOG | Fault.NONFINITE | Fault.HOST_STOP | Fault.PROFILE_INVALID)
ABORT_FLAGS |= int(Fault.RESET)


def stop_tolerance_mm(stop_depth_mm: float) -> float:
    """How far past the stop depth a reported drill depth may be and still be the stop, mm.

    One encoder count (0.1 um) plus the float32 rounding of the stop depth on the wire.
    """
    return ENCODER_M * 1e3 + abs(stop_depth_mm) * 2.0**-22


def fault_names(bits: int) -> list[str]:
    return [f.name.lower() for f in Fault if bits & f]


class TelemetryWatch:
    """The host's checks of the device's telemetry (module docstring)."""

    def __init__(self, stop_depth_mm: float, watchdog_s: float, clock_s: float) -> None:
        self.stop_depth_mm = stop_depth_mm
        self.limit_mm = stop_depth_mm + stop_tolerance_mm(stop_depth_mm)
        self.silent_s = SILENT_WATCHDOG_PERIODS * watchdog_s
        self.last_heard_s = clock_s

    def check(
        self, samples: Sequence[TelemetrySample], clock_s: float, lost_session: bool
    ) -> tuple[str, str, TelemetrySample | None] | None:
        """``(kind, message, sample)`` of the first violation, or None."""
        if samples:
            self.last_heard_s = clock_s
        for s in samples:
            if not (math.isfinite(s.drill_mm) and math.isfinite(s.master_mm)):
                return "device_fault", "the device reported a non-finite position", s
            if s.drill_mm > self.limit_mm:
                return (
                    "drill_past_stop",
                    f"the device reported the drill at {s.drill_mm:.4f} mm, past the stop "
                    f"depth {self.stop_depth_mm:.4f} mm",
                    s,
                )
            if s.faults & ABORT_FLAGS:
                names = ", ".join(fault_names(s.faults & ABORT_FLAGS))
                return "device_fault", f"the device raised {names}", s
            if s.state not in (DeviceState.CUTTING, DeviceState.STOPPED):
                return (
                    "device_fault",
                    f"the device left the armed states ({STATE_NAMES[s.state]})",
                    s,
                )
        if lost_session:
            return "device_reset", "the device came back without the session (it rebooted)", None
        silent = clock_s - self.last_heard_s
        if silent > self.silent_s:
            return (
                "telemetry_silent",
                f"no telemetry for {silent * 1e3:.0f} ms (more than {SILENT_WATCHDOG_PERIODS} "
                f"watchdog periods of {self.silent_s / SILENT_WATCHDOG_PERIODS * 1e3:.0f} ms)",
                None,
            )
        return None
