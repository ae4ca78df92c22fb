"""The host's watch of a session's telemetry (docs/protocol.md section 5).

:class:`TelemetryWatch` decides from the host's own clock and its own bounds, never from what
the device claims about itself. It finds the first reason to end an armed session:

* a report the host cannot interpret or trust (:meth:`TelemetryWatch.malformed`): a non-finite
  number, a value outside the device's LIMITS or its physics
  (:func:`ctdrill.haptics.limits.telemetry_problem`: a position outside the travel, a force
  beyond the peak, a reading of the hand or a speed no hand makes), a state or a fault flag
  this protocol does not define, the table of another upload, device time that does not
  advance by its ticks (backwards, frozen, a jump) or runs ahead of the host's clock; such a
  sample is not recorded;
* the drill reported beyond the stop depth by more than :func:`stop_tolerance_mm`, a fault flag
  of :data:`ABORT_FLAGS`, a state other than cutting or stopped (recorded, then the session
  ends);
* a device that came back without the session, or whose FAULT reports the host cannot
  interpret;
* telemetry silent for longer than the host's bound (:func:`ctdrill.haptics.limits.silence_bound_s`,
  at most 100 ms whatever the device announced).

:func:`ctdrill.haptics.run.run_session` acts on it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from ctdrill.haptics.codes import KNOWN_FAULT_BITS, KNOWN_STATES
from ctdrill.haptics.device import DeviceInfo, TelemetrySample
from ctdrill.haptics.limits import TELEMETRY_NUMBERS, silence_bound_s, telemetry_problem
from ctdrill.haptics.plant import ENCODER_M, TRAVEL_MM
from ctdrill.haptics.profile_table import MAX_PROFILE_STEPS
from ctdrill.haptics.protocol import DeviceState, Fault, Limits
from ctdrill.haptics.renderer import (
    CONTINUOUS_FORCE_N,
    PEAK_FORCE_N,
    THERMAL_BUDGET_N2_S,
    WATCHDOG_S,
)
from ctdrill.haptics.session import STATE_NAMES
from ctdrill.haptics.tick import TICK_HZ

#: Fault flags that end a session (the limits PEAK, THERMAL and TRAVEL are logged only).
ABORT_FLAGS = int(Fault.WATCHDOG | Fault.NONFINITE | Fault.HOST_STOP | Fault.PROFILE_INVALID)
ABORT_FLAGS |= int(Fault.RESET)
#: Device time between two samples may differ from their ticks' worth by this much, s (the
#: microsecond clock's rounding).
TICK_TIME_TOLERANCE_S = 2e-6
#: Device time may run ahead of the host's clock by this fraction plus :data:`CLOCK_SLACK_S`
#: (crystals differ by 1e-4; the slack covers the ARM acknowledgement's transit).
CLOCK_RATE_TOLERANCE = 0.01
CLOCK_SLACK_S = 0.05
#: The emulated master's LIMITS (what a watch holds a device to when none was announced).
DEFAULT_LIMITS = Limits(
    PEAK_FORCE_N,
    CONTINUOUS_FORCE_N,
    THERMAL_BUDGET_N2_S,
    round(WATCHDOG_S * 1000),
    MAX_PROFILE_STEPS,
    *TRAVEL_MM,
)


def stop_tolerance_mm(stop_depth_mm: float) -> float:
    """How far past the stop depth a reported drill depth may be and still be the stop, mm.

    One encoder count (0.1 um) plus the float32 rounding of the stop depth on the wire.
    """
    return ENCODER_M * 1e3 + abs(stop_depth_mm) * 2.0**-22


def fault_names(bits: int) -> list[str]:
    """Names of the defined flags in ``bits`` (lower case)."""
    return [f.name.lower() for f in Fault if bits & f]


@dataclass(frozen=True)
class Finding:
    """Why the session must end.

    Attributes
    ----------
    kind : str
        ``device_fault``, ``device_clock``, ``drill_past_stop``, ``device_reset`` or
        ``telemetry_silent``.
    message : str
        What the host saw, in words.
    sample : TelemetrySample or None
        The sample that showed it (None: no sample did).
    recorded : int
        How many of the checked samples the session may record: those before ``sample``, and
        ``sample`` itself when it was well formed (a drill past the stop is recorded; a NaN
        is not).
    trusted : bool
        ``sample`` itself can be trusted (False: it is the report the host could not trust).
    """

    kind: str
    message: str
    sample: TelemetrySample | None
    recorded: int
    trusted: bool = True

    def dated(self, t0_device_s: float | None, session_s: float) -> str:
        """The message with when it happened: the sample's session time (device clock from
        ``t0_device_s``) when it was recorded, else ``session_s`` on the host's clock."""
        s = self.sample
        if s is not None and self.trusted and t0_device_s is not None:
            return f"{self.message} at {s.time_s - t0_device_s:.4f} s"
        return f"{self.message} (host clock {session_s:.4f} s into the session)"


class TelemetryWatch:
    """The host's checks of an armed session's telemetry (module docstring).

    Parameters
    ----------
    stop_depth_mm : float
        The stop depth the host uploaded.
    clock_s : float
        The host's clock when the device acknowledged ARM, s.
    watchdog_ms : int
        The device's watchdog (from LIMITS, already within the host's bounds).
    tick_rate_hz : int
        The device's control rate (from VERSION, within the host's bounds).
    table_crc32 : int, optional
        CRC-32 of the uploaded table: telemetry naming another table ends the session.
    limits : Limits, optional
        What the device announced (already within the host's bounds): every reported value is
        held to it (default: the emulated master's).
    """

    @classmethod
    def for_session(
        cls, info: DeviceInfo, stop_depth_mm: float, table_crc32: int, clock_s: float
    ) -> TelemetryWatch:
        """The watch of a session armed at ``clock_s`` on a device that announced ``info``."""
        return cls(
            stop_depth_mm,
            clock_s,
            watchdog_ms=info.limits.watchdog_ms,
            tick_rate_hz=info.version.tick_rate_hz,
            table_crc32=table_crc32,
            limits=info.limits,
        )

    def __init__(
        self,
        stop_depth_mm: float,
        clock_s: float,
        *,
        watchdog_ms: int = round(WATCHDOG_S * 1000),
        tick_rate_hz: int = TICK_HZ,
        table_crc32: int | None = None,
        limits: Limits | None = None,
    ) -> None:
        self.limits = limits or DEFAULT_LIMITS
        self.stop_depth_mm = stop_depth_mm
        self.limit_mm = stop_depth_mm + stop_tolerance_mm(stop_depth_mm)
        self.silent_s = silence_bound_s(watchdog_ms)
        self.tick_s = 1.0 / tick_rate_hz
        self.table_crc32 = table_crc32
        self.start_clock_s = clock_s
        self.last_heard_s = clock_s
        self._prev: TelemetrySample | None = None
        self._first_time_s: float | None = None

    def malformed(self, s: TelemetrySample, clock_s: float) -> tuple[str, str] | None:
        """``(kind, message)`` if the host cannot trust ``s`` (module docstring), else None;
        a trusted sample becomes the reference for the next one's clock."""
        for name in TELEMETRY_NUMBERS:
            value = getattr(s, name)
            if not math.isfinite(value):
                return "device_fault", f"the device reported a non-finite {name} ({value})"
        beyond = telemetry_problem(s, self.limits)
        if beyond is not None:
            return "device_fault", f"the device reported {beyond}"
        if s.state not in KNOWN_STATES:
            return "device_fault", f"the device reported an undefined state {s.state}"
        unknown = s.faults & ~KNOWN_FAULT_BITS
        if unknown:
            return "device_fault", f"the device reported an undefined fault flag 0x{unknown:04x}"
        if self.table_crc32 is not None and s.table_crc32 != self.table_crc32:
            return (
                "device_fault",
                f"the device reports table 0x{s.table_crc32:08x}, not the uploaded "
                f"0x{self.table_crc32:08x}",
            )
        prev = self._prev
        if prev is not None:
            dt = s.time_s - prev.time_s
            ticks = (s.tick - prev.tick) & 0xFFFFFFFF
            if not dt > 0.0:
                verb = "stood still" if dt == 0.0 else "ran backwards"
                return (
                    "device_clock",
                    f"device time {verb} ({prev.time_s:.6f} s then {s.time_s:.6f} s)",
                )
            if abs(dt - ticks * self.tick_s) > TICK_TIME_TOLERANCE_S:
                return (
                    "device_clock",
                    f"device time advanced {dt:.6g} s over {ticks} ticks "
                    f"({ticks * self.tick_s:.6g} s)",
                )
        first = self._first_time_s if self._first_time_s is not None else s.time_s
        device_s = s.time_s - first
        host_s = clock_s - self.start_clock_s
        if device_s > host_s * (1.0 + CLOCK_RATE_TOLERANCE) + CLOCK_SLACK_S:
            return (
                "device_clock",
                f"device time ran ahead of the host's clock ({device_s:.3f} s in {host_s:.3f} s)",
            )
        self._prev = s
        self._first_time_s = first
        return None

    def trusted(self, samples: Sequence[TelemetrySample], clock_s: float) -> list[TelemetrySample]:
        """The samples up to the first the host cannot trust (the device's last words after a
        STOP are recorded with the same care)."""
        out = []
        for s in samples:
            if self.malformed(s, clock_s) is not None:
                break
            out.append(s)
        return out

    def check(
        self,
        samples: Sequence[TelemetrySample],
        clock_s: float,
        lost_session: bool,
        untrusted: str | None = None,
    ) -> Finding | None:
        """The first reason to end the session in this block's ``samples``, or None."""
        if samples:
            self.last_heard_s = clock_s
        for i, s in enumerate(samples):
            bad = self.malformed(s, clock_s)
            if bad is not None:
                return Finding(bad[0], bad[1], s, i, trusted=False)
            if s.drill_mm > self.limit_mm:
                return Finding(
                    "drill_past_stop",
                    f"the device reported the drill at {s.drill_mm:.4f} mm, past the stop "
                    f"depth {self.stop_depth_mm:.4f} mm",
                    s,
                    i + 1,
                )
            if s.faults & ABORT_FLAGS:
                names = ", ".join(fault_names(s.faults & ABORT_FLAGS))
                return Finding("device_fault", f"the device raised {names}", s, i + 1)
            if s.state not in (DeviceState.CUTTING, DeviceState.STOPPED):
                return Finding(
                    "device_fault",
                    f"the device left the armed states ({STATE_NAMES[s.state]})",
                    s,
                    i + 1,
                )
        n = len(samples)
        if untrusted is not None:
            return Finding("device_fault", untrusted, None, n)
        if lost_session:
            return Finding(
                "device_reset", "the device came back without the session (it rebooted)", None, n
            )
        silent = clock_s - self.last_heard_s
        if silent > self.silent_s:
            return Finding(
                "telemetry_silent",
                f"no telemetry for {silent * 1e3:.1f} ms (the host's bound: "
                f"{self.silent_s * 1e3:.0f} ms)",
                None,
                n,
            )
        return None
