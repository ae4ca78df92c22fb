"""The host's watch of the telemetry: each reason to end a session, at its boundary."""

from __future__ import annotations

import math
import struct

import pytest

from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.protocol import DeviceState, Fault
from ctdrill.haptics.watch import TelemetryWatch, stop_tolerance_mm


def _sample(drill_mm: float, state: int = DeviceState.STOPPED, faults: int = 0) -> TelemetrySample:
    return TelemetrySample(0.0, 0, drill_mm + 1.0, drill_mm, 0.0, 10.0, 10.0, state, faults, 0)


def test_stop_tolerance_is_one_encoder_count_plus_float32_rounding() -> None:
    stop = 10.8
    assert stop_tolerance_mm(stop) == pytest.approx(1e-4 + 10.8 * 2.0**-22)
    wire = struct.unpack("<f", struct.pack("<f", stop))[0]  # the stop depth the device holds
    assert wire - stop < stop_tolerance_mm(stop) - 1e-4
    watch = TelemetryWatch(stop, 0.05, 0.0)
    assert watch.check([_sample(wire + 1e-4)], 0.0, False) is None  # at the device's stop + 1 count
    found = watch.check([_sample(stop + 2.1e-4)], 0.0, False)
    assert found is not None and found[0] == "drill_past_stop"
    found = watch.check([_sample(math.nan)], 0.0, False)
    assert found is not None and found[0] == "device_fault"


@pytest.mark.parametrize(
    ("state", "faults", "ends"),
    [
        (DeviceState.CUTTING, 0, False),
        (DeviceState.STOPPED, Fault.PEAK_LIMIT | Fault.THERMAL_LIMIT | Fault.TRAVEL_LIMIT, False),
        (DeviceState.CUTTING, Fault.WATCHDOG, True),
        (DeviceState.CUTTING, Fault.RESET, True),
        (DeviceState.SAFE, Fault.HOST_STOP, True),
        (DeviceState.IDLE, 0, True),
    ],
)
def test_device_faults_and_states(state: int, faults: int, ends: bool) -> None:
    found = TelemetryWatch(5.0, 0.05, 0.0).check([_sample(1.0, state, faults)], 0.0, False)
    assert (found is not None) == ends


def test_silence_beyond_two_watchdog_periods_and_a_lost_session() -> None:
    watch = TelemetryWatch(5.0, 0.05, 0.0)
    assert watch.check([], 0.1, False) is None  # 100 ms: not more than 2 periods
    found = watch.check([], 0.1001, False)
    assert found is not None and found[0] == "telemetry_silent"
    assert watch.check([_sample(1.0)], 2.0, False) is None  # heard again: the clock restarts
    found = watch.check([], 2.0, True)
    assert found is not None and found[0] == "device_reset"
