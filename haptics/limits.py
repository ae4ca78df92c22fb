"""What the host accepts of a device's VERSION and LIMITS (docs/protocol.md section 2.5).

The host decides from its own clock and its own bounds: a device announcing limits outside
:data:`LIMITS_BOUNDS` (a watchdog of 65 s, a peak force of 1 kN, a NaN travel) is refused
before anything is uploaded, and the host's silence bound is its own (:func:`silence_bound_s`,
at most :data:`HOST_SILENCE_S` whatever the device announces).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

from ctdrill.haptics.protocol import PROTOCOL_VERSION, Fault, Limits, Version

if TYPE_CHECKING:
    from ctdrill.haptics.device import TelemetrySample

#: The host ends a session after this long without telemetry, s, at the most.
HOST_SILENCE_S = 0.100
#: Telemetry silent for more than this many device watchdog periods ends the session (when
#: that is shorter than :data:`HOST_SILENCE_S`).
SILENT_WATCHDOG_PERIODS = 2
#: Control rates the host accepts in VERSION, Hz (1 kHz is haptic rendering's floor).
TICK_RATE_HZ = (1_000, 100_000)
#: The numbers of a TELEMETRY report (each must be finite).
TELEMETRY_NUMBERS = ("master_mm", "drill_mm", "velocity_mm_s", "force_cmd_n", "force_est_n")
#: A reported position may lie beyond the announced travel by this much, mm (encoder counts and
#: the float32 rounding of the travel's ends).
TRAVEL_TOLERANCE_MM = 1e-3
#: A reported force may exceed its bound by this much, N (float32 rounding).
FORCE_TOLERANCE_N = 1e-3
#: The device's reading of the hand may overshoot the hand in a transient (89 N for a 78 N push
#: meeting the wall on the emulated master, 57 N for 40 N): beyond this many times the peak
#: force no hand pushes or pulls on the master's axis.
HAND_READING_PEAKS = 1.5
#: On a mechanical end stop (TRAVEL_LIMIT in the report, or the master within
#: :data:`END_STOP_NEAR_MM` of either end: it rebounds a few micrometres while the reading
#: settles) the reading takes the stage's impact for the hand (660 N for the emulated master
#: stopped from 4.3 m/s, decaying at 1000 rad/s): at most this many times the peak force.
END_STOP_READING_MULTIPLE = 20.0
END_STOP_NEAR_MM = 1.0
#: The master's speed at the most, mm/s (the emulated master reaches 4.3 m/s pushed at 78 N
#: through air over its whole travel; 10 m/s is no hand-held drill's stage).
MAX_SPEED_MM_S = 10_000.0


@dataclass(frozen=True)
class Bound:
    """The closed range ``lo .. hi`` a LIMITS field must lie in (finite), and why."""

    field: str
    lo: float
    hi: float
    unit: str
    why: str


#: One bound per LIMITS field, in the message's order.
LIMITS_BOUNDS = (
    Bound("peak_force_n", 1.0, 100.0, "N", "a hand's thrust; ctdrill's hands push 78 N at most"),
    Bound("continuous_force_n", 1.0, 100.0, "N", "and at most peak_force_n"),
    Bound("thermal_budget_n2_s", 1.0, 1.0e5, "N^2 s", "16 s at 78 N above the rating at most"),
    Bound(
        "watchdog_ms",
        20,
        50,
        "ms",
        "the host beats every 10 ms: shorter trips on one late beat; longer keeps pushing a "
        "hand after its host is gone",
    ),
    Bound("max_profile_steps", 1, 4096, "rows", "the table's u16 index, 48 KiB"),
    Bound("travel_min_mm", -500.0, 0.0, "mm", "the entry point (depth 0) within travel"),
    Bound("travel_max_mm", 1.0, 500.0, "mm", "the entry point (depth 0) within travel"),
)


def silence_bound_s(watchdog_ms: int) -> float:
    """How long the host lets telemetry be silent, s: two device watchdog periods, at most
    :data:`HOST_SILENCE_S` whatever the device announced."""
    return min(HOST_SILENCE_S, SILENT_WATCHDOG_PERIODS * watchdog_ms / 1000.0)


def device_info_problem(version: Version, limits: Limits) -> str | None:
    """Why the host refuses a device that announced ``version`` and ``limits`` (None: it
    accepts them): a field outside its bound or not finite, the continuous rating above the
    peak, another protocol version, a control rate outside :data:`TICK_RATE_HZ`."""
    if version.protocol_version != PROTOCOL_VERSION:
        return f"VERSION protocol {version.protocol_version}, expected {PROTOCOL_VERSION}"
    lo, hi = TICK_RATE_HZ
    if not lo <= version.tick_rate_hz <= hi:
        return f"VERSION tick_rate_hz {version.tick_rate_hz}, outside {lo}..{hi} Hz"
    values = {f.name: getattr(limits, f.name) for f in fields(limits)}
    for bound in LIMITS_BOUNDS:
        value = values[bound.field]
        if not (math.isfinite(value) and bound.lo <= value <= bound.hi):
            return (
                f"LIMITS {bound.field} {value:g}, outside {bound.lo:g}..{bound.hi:g} {bound.unit}"
            )
    if limits.continuous_force_n > limits.peak_force_n:
        return (
            f"LIMITS continuous_force_n {limits.continuous_force_n:g} N above peak_force_n "
            f"{limits.peak_force_n:g} N"
        )
    return None


def table_problem(limits: Limits, n_steps: int, stop_depth_mm: float) -> str | None:
    """Why a table of ``n_steps`` rows stopping at ``stop_depth_mm`` does not fit the device
    (None: it fits)."""
    if n_steps > limits.max_profile_steps:
        return f"the table has {n_steps} rows; the device takes at most {limits.max_profile_steps}"
    if stop_depth_mm > limits.travel_max_mm:
        return (
            f"the stop depth {stop_depth_mm:g} mm lies beyond the device's travel "
            f"({limits.travel_max_mm:g} mm)"
        )
    return None


def telemetry_problem(sample: TelemetrySample, limits: Limits) -> str | None:
    """Why a TELEMETRY report (finite, already checked) lies outside what the device announced
    and what its physics allow (None: within them): the master or the drill outside the
    travel, a speed beyond
    :data:`MAX_SPEED_MM_S`, a rendered force outside ``-continuous_force_n ..
    peak_force_n`` (it pulls only through the release damper, at most the continuous rating),
    a reading of the hand beyond :data:`HAND_READING_PEAKS` times the peak force
    (:data:`END_STOP_READING_MULTIPLE` on an end stop)."""
    lo = limits.travel_min_mm - TRAVEL_TOLERANCE_MM
    hi = limits.travel_max_mm + TRAVEL_TOLERANCE_MM
    for name in ("master_mm", "drill_mm"):
        value = getattr(sample, name)
        if not lo <= value <= hi:
            return (
                f"{name} {value:g} mm, outside its travel {limits.travel_min_mm:g}.."
                f"{limits.travel_max_mm:g} mm"
            )
    if abs(sample.velocity_mm_s) > MAX_SPEED_MM_S:
        return f"velocity_mm_s {sample.velocity_mm_s:g} mm/s, beyond {MAX_SPEED_MM_S:g} mm/s"
    peak = limits.peak_force_n
    if not (
        -limits.continuous_force_n - FORCE_TOLERANCE_N
        <= sample.force_cmd_n
        <= peak + FORCE_TOLERANCE_N
    ):
        return (
            f"force_cmd_n {sample.force_cmd_n:g} N, outside -{limits.continuous_force_n:g}.."
            f"{peak:g} N"
        )
    on_end_stop = bool(sample.faults & Fault.TRAVEL_LIMIT) or not (
        limits.travel_min_mm + END_STOP_NEAR_MM
        < sample.master_mm
        < limits.travel_max_mm - END_STOP_NEAR_MM
    )
    reading = (END_STOP_READING_MULTIPLE if on_end_stop else HAND_READING_PEAKS) * peak
    if abs(sample.force_est_n) > reading:
        where = " on an end stop" if on_end_stop else ""
        return f"force_est_n {sample.force_est_n:g} N, beyond {reading:g} N{where}"
    return None
