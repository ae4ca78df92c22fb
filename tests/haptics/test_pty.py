"""A pty round trip: ``ctdrill emulate --pty-link`` in a subprocess, SerialDevice on the link:
the device's safety, a second rehearsal on the same emulator, the exclusive port, an emergency
stop after another host took the session.

Durations are counted in device ticks from the telemetry (the emulator's clock slows down with
a loaded host); the one real-time duty left is the host's: a heartbeat within the 50 ms
watchdog. A trip that this test's own heartbeat gap explains reruns the case on a fresh
emulator (``with_fresh_emulator``); a trip with the host on time fails it.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from ctdrill.haptics.device import DeviceError
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState, Fault, Hello, OperatorKind, encode
from ctdrill.haptics.renderer import WATCHDOG_S
from ctdrill.haptics.serial_device import SerialDevice
from ctdrill.haptics.tick import TICK_HZ
from tests.haptics.emulator_process import (
    beat,
    demo_rehearsal,
    emulator_on_pty,
    silent,
    with_fresh_emulator,
)


@pytest.fixture
def emulator(tmp_path: Path) -> Iterator[Path]:
    with emulator_on_pty(tmp_path / "ctdrill-device") as link:
        yield link


@pytest.mark.timeout(180)
def test_round_trip_and_safety_over_a_pty(tmp_path: Path) -> None:
    with_fresh_emulator(tmp_path, _round_trip)


def _round_trip(link: Path, _emulator: subprocess.Popen[str]) -> None:
    dev = SerialDevice(str(link))
    try:
        info = dev.hello()
        assert info.version.tick_rate_hz == TICK_HZ and info.limits.watchdog_ms == 50
        table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=0.5)
        dev.upload_profile(table)
        dev.arm()
        # 1 s of device time pushing 20 N, and until the drill has stopped
        pushed = beat(dev, 20.0, TICK_HZ, until=lambda s: s[-1].state != DeviceState.CUTTING)
        samples = pushed.samples
        assert all(s.state != DeviceState.SAFE for s in samples), (
            f"tripped while the host beat (its largest heartbeat gap {pushed.max_gap_s:.3f} s, "
            f"the watchdog {WATCHDOG_S} s)"
        )
        # Telemetry at 1 kHz device time, in device-clock order, and the stop holds.
        assert len(samples) > 300
        ticks = [s.tick for s in samples]
        assert ticks == sorted(ticks) and all(b - a == 10 for a, b in itertools.pairwise(ticks))
        assert max(s.drill_mm for s in samples) <= table.stop_depth_mm
        assert samples[-1].state == DeviceState.STOPPED
        assert samples[-1].drill_mm == pytest.approx(0.5, abs=1e-6)
        assert samples[-1].force_cmd_n > 15.0
        # Same safety behaviour as the simulator: no frames for > 50 ms -> safe, latched (watched
        # for 4 watchdog periods of device time).
        late = silent(dev, lambda s: len(s) > 0 and s[-1].tick - samples[-1].tick > 2000)
        assert late[-1].state == DeviceState.SAFE and late[-1].force_cmd_n == 0.0
        assert late[-1].faults & Fault.WATCHDOG
        trips = [t for t, f in dev.fault_reports if f.faults & Fault.WATCHDOG]
        assert trips
        with pytest.raises(DeviceError, match="NOT_RETRACTED"):
            dev.arm()  # the hand is still pushed deep: no force step on re-arming
        # retract until the handle is back at the cut front (arming then steps no force)
        beat(dev, -10.0, 100, until=lambda s: s[-1].master_mm <= s[-1].drill_mm)
        dev.arm()
        dev.disarm()
        idle = beat(dev, 0.0, 500).samples  # 50 ms of device time
        assert idle[-1].state == DeviceState.IDLE and idle[-1].force_cmd_n == 0.0
    finally:
        dev.close()


def _rehearse(link: Path, out: Path, operator: str, duration: str) -> int:
    return main(demo_rehearsal(out, operator, duration, "--device", f"serial:{link}"))


@pytest.mark.timeout(120)
def test_a_second_rehearsal_on_the_same_emulator_works(
    emulator: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The first session cuts to the stop and ends; the simulated hand keeps pushing the disarmed
    # master to the end of its travel. The second finds the handle deep (ARM would be refused
    # NOT_RETRACTED, exit 2), retracts it, arms and cuts to the stop again; a third pulls back
    # (push:-10), after the same retraction. None is refused. (A host stalled for 50 ms by a
    # loaded machine trips the device's watchdog, exit 3: that is the device doing its job, so
    # the checks of a complete session apply to the sessions that completed.)
    first, second, back = tmp_path / "first", tmp_path / "second", tmp_path / "back"
    code = _rehearse(emulator, first, "push:30", "0.8")
    assert code in (0, 3), capsys.readouterr().err
    a = json.loads((first / "summary.json").read_text())
    assert a["retraction"] is None
    code = _rehearse(emulator, second, "push:30", "0.8")
    out, err = capsys.readouterr()
    assert code in (0, 3), err
    b = json.loads((second / "summary.json").read_text())
    assert b["retraction"]["from_mm"] > 1.0 and b["retraction"]["to_mm"] <= 0.0
    assert "retracting it" in out and b["max_drill_mm"] <= b["device_stop_depth_mm"]
    if code == 0:
        assert b["time_to_stop_s"] is not None
        assert b["wall_held"] is True  # 30 N rests 0.14 mm past the stopped drill
    code = _rehearse(emulator, back, "push:-10", "0.3")
    assert code in (0, 3), capsys.readouterr().err
    c = json.loads((back / "summary.json").read_text())
    assert c["retraction"] is not None and c["max_drill_mm"] <= 0.5
    if code == 0:
        assert c["final_master_mm"] < 0.0


@pytest.mark.timeout(60)
def test_the_port_is_opened_exclusively(
    emulator: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    first = SerialDevice(str(emulator))
    try:
        with pytest.raises(DeviceError, match="in use by another program"):
            SerialDevice(str(emulator))
        assert _rehearse(emulator, tmp_path / "out", "push:20", "0.5") == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "in use by another program" in err
        assert not (tmp_path / "out").exists()
    finally:
        first.close()
    SerialDevice(str(emulator)).close()  # released with the first


@pytest.mark.timeout(60)
def test_an_emergency_stop_works_after_another_host_took_the_session(emulator: Path) -> None:
    # Host A is armed and pushing; another program (no lock: a console, a stray script) opens
    # the port and sends HELLO: the device is now in its session. A's STOP and DISARM are still
    # obeyed and acknowledged in A's session (version 2 refused them BAD_SESSION).
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=20.0)
    dev = SerialDevice(str(emulator))
    other = os.open(os.readlink(emulator), os.O_RDWR | os.O_NOCTTY)
    try:
        dev.hello()
        dev.upload_profile(table)
        dev.arm()
        assert beat(dev, 20.0, 3000).samples[-1].state == DeviceState.CUTTING  # 300 ms
        os.write(other, encode(Hello(host_token=0xCAFE), seq=1))  # the other host's session
        for _ in range(5):  # A's own frames are now refused (BAD_SESSION, in B's session)
            dev.heartbeat()
            dev.set_operator(int(OperatorKind.PUSH), 20.0)
            dev.wait(0.01)
        dev.stop()  # acknowledged in A's session: no DeviceError
        dev.disarm()
        dev.hello()  # A looks again: the stop is latched, whoever holds the session
        samples = silent(dev, lambda s: len(s) > 0)
    finally:
        os.close(other)
        dev.close()
    assert samples and samples[-1].state == DeviceState.SAFE
    assert samples[-1].faults & Fault.HOST_STOP and samples[-1].force_cmd_n == 0.0
