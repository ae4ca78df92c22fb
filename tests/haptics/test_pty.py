"""A pty round trip: ``ctdrill emulate --pty-link`` in a subprocess, SerialDevice on the link."""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from ctdrill.haptics.device import DeviceError
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState, Fault, OperatorKind
from ctdrill.haptics.serial_device import SerialDevice
from tests.haptics.emulator_process import emulator_on_pty


@pytest.fixture
def emulator(tmp_path: Path) -> Iterator[Path]:
    with emulator_on_pty(tmp_path / "ctdrill-device") as link:
        yield link


def _beat(dev: SerialDevice, seconds: float, force_n: float) -> list:
    samples = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        dev.heartbeat()
        dev.set_operator(int(OperatorKind.PUSH), force_n)
        dev.wait(0.01)
        samples += dev.poll()
    return samples


@pytest.mark.timeout(60)
def test_round_trip_and_safety_over_a_pty(emulator: Path) -> None:
    dev = SerialDevice(str(emulator))
    try:
        info = dev.hello()
        assert info.version.tick_rate_hz == 10_000 and info.limits.watchdog_ms == 50
        table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=0.5)
        dev.upload_profile(table)
        dev.arm()
        samples = _beat(dev, 1.0, 20.0)
        # Telemetry at 1 kHz device time, in device-clock order, and the stop holds.
        assert len(samples) > 300
        ticks = [s.tick for s in samples]
        assert ticks == sorted(ticks) and all(b - a == 10 for a, b in itertools.pairwise(ticks))
        assert max(s.drill_mm for s in samples) <= table.stop_depth_mm
        assert samples[-1].state == DeviceState.STOPPED
        assert samples[-1].drill_mm == pytest.approx(0.5, abs=1e-6)
        assert samples[-1].force_cmd_n > 15.0
        # Same safety behaviour as the simulator: no frames for > 50 ms -> safe, latched.
        dev.wait(0.2)
        late = dev.poll()
        assert late[-1].state == DeviceState.SAFE and late[-1].force_cmd_n == 0.0
        assert late[-1].faults & Fault.WATCHDOG
        trips = [t for t, f in dev.fault_reports if f.faults & Fault.WATCHDOG]
        assert trips and all(s.state != DeviceState.SAFE for s in samples)
        with pytest.raises(DeviceError, match="NOT_RETRACTED"):
            dev.arm()  # the hand is still pushed deep: no force step on re-arming
        _beat(dev, 0.3, -10.0)  # retract
        dev.arm()
        dev.disarm()
        idle = _beat(dev, 0.05, 0.0)
        assert idle[-1].state == DeviceState.IDLE and idle[-1].force_cmd_n == 0.0
    finally:
        dev.close()
