"""Fault injection on the device link, pinned as regressions (issue 15).

Classes: a looped-back line, replayed frames, a frozen device (SIGSTOP of the emulator), a
device lying past the stop, the host's own write error, a host killed mid-session. Each pins:
no force without a live host, the host ends with STOP and DISARM and exit code 3 after a fault
(never 0), the records whole (the previous session intact, or the new one with its summary).
The serial cases drive ``ctdrill emulate`` over a real pseudo-terminal.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from ctdrill.haptics.device import DeviceError, TelemetrySample
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import (
    Arm,
    DeviceState,
    Fault,
    FrameReader,
    Heartbeat,
    Hello,
    Message,
    Nak,
    NakReason,
    Packet,
    Telemetry,
    encode,
)
from ctdrill.haptics.renderer import WATCHDOG_S
from ctdrill.haptics.serial_device import SerialDevice
from ctdrill.haptics.sim import SimLink
from tests.haptics.emulator_process import (
    ROOT,
    HostLate,
    beat,
    demo_rehearsal,
    host_late,
    with_fresh_emulator,
)
from tests.haptics.wire import Wire

SLAB = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=20.0)


def _rehearse_args(out: Path, *extra: str, duration: str = "2") -> list[str]:
    return demo_rehearsal(out, "push:20", duration, *extra)


def _armed_pushing(dev: SerialDevice, ticks: int, force_n: float = 20.0) -> None:
    """Arm and push for ``ticks`` of device time; the device is then cutting."""
    dev.hello()
    dev.upload_profile(SLAB)
    dev.arm()
    pushed = beat(dev, force_n, ticks)
    last = pushed.samples[-1]
    assert last.state == DeviceState.CUTTING and last.force_cmd_n > 5.0, (
        last,
        f"the host's largest heartbeat gap {pushed.max_gap_s:.3f} s (watchdog {WATCHDOG_S} s)",
    )


def _telemetry(data: bytes) -> list[Telemetry]:
    return [
        p.message
        for p in FrameReader().feed(data)
        if isinstance(p, Packet) and isinstance(p.message, Telemetry)
    ]


def _wait_armed(out: Path, timeout_s: float = 20.0) -> None:
    """Until the rehearsal writing ``out`` has logged 100 ms of armed telemetry."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        for csv in out.parent.glob(f".{out.name}.ctdrill-new-*/session.csv"):
            if csv.read_text().count("\n") > 100:
                return
        time.sleep(0.02)
    raise AssertionError("the rehearsal did not arm")


# ---------------------------------------------------------------- the device side, in-process


def _armed_emulator() -> tuple[DeviceEmulator, Wire]:
    emu = DeviceEmulator(nonce_seed=5)
    wire = Wire(emu)
    wire.hello()
    for m in SLAB.upload_messages():
        wire.send(m)
    wire.send(Arm(SLAB.crc32))
    wire.packets()
    return emu, wire


def _ticks_until_safe(emu: DeviceEmulator, feed: bytes, seconds: float) -> float | None:
    """Feed ``feed`` to the device every 10 ms; the device time it went safe, or None."""
    for _ in range(round(seconds / 0.01)):
        emu.receive(feed)
        emu.run_ticks(100)
        if emu.renderer.state == DeviceState.SAFE:
            return emu.now_s
    return None


def test_looped_back_device_frames_never_feed_the_watchdog() -> None:
    emu, wire = _armed_emulator()
    last_host = emu.now_s
    echoed = b""
    for _ in range(20):  # 200 ms of a looped-back line: the device hears only itself
        emu.receive(echoed)
        emu.run_ticks(100)
        echoed = emu.take_output()
    assert emu.renderer.state == DeviceState.SAFE and emu.renderer.faults & Fault.WATCHDOG
    assert emu.renderer.safe_since_s - last_host <= WATCHDOG_S + 1e-4
    assert emu.renderer.force_cmd_n == 0.0
    assert all(t.force_cmd_n == 0.0 for t in _telemetry(echoed))
    assert not any(isinstance(p.message, Nak) for p in wire.packets())  # no NAK storm


def test_replayed_or_foreign_frames_do_not_keep_it_armed() -> None:
    emu, wire = _armed_emulator()
    beat = wire.frame(Heartbeat())
    emu.receive(beat)  # accepted once
    last_host = emu.now_s
    assert len(beat) == 24
    assert _ticks_until_safe(emu, beat, 0.3) is not None  # the same 24 bytes every 10 ms
    assert emu.renderer.safe_since_s - last_host <= WATCHDOG_S + 1e-4
    naks = {p.message for p in wire.packets() if isinstance(p.message, Nak)}
    assert naks == {Nak(0x22, wire.seq, NakReason.STALE_SEQUENCE)}
    # frames of another session (an earlier one, or none) are refused too, whatever their seq
    emu, wire = _armed_emulator()
    foreign = encode(Heartbeat(), seq=wire.seq + 1000, session=wire.session ^ 1)
    unsessioned = encode(Heartbeat(), seq=wire.seq + 1001, session=0)
    assert _ticks_until_safe(emu, foreign + unsessioned, 0.3) is not None
    reasons = {p.message.reason for p in wire.packets() if isinstance(p.message, Nak)}
    assert reasons == {NakReason.BAD_SESSION}


def test_a_replayed_hello_only_disarms() -> None:
    emu, wire = _armed_emulator()
    old = wire.session
    emu.receive(encode(Hello(host_token=0x5EED), seq=1))  # the session's HELLO, replayed
    assert emu.renderer.state == DeviceState.IDLE and emu.renderer.force_cmd_n == 0.0
    assert emu.session not in (0, old)
    wire.send(
        Arm(SLAB.crc32)
    )  # the old session's frames are refused: it cannot be re-armed by them
    naks = [p.message for p in wire.packets() if isinstance(p.message, Nak)]
    assert naks == [Nak(0x20, wire.seq, NakReason.BAD_SESSION)]
    assert emu.renderer.state == DeviceState.IDLE


def test_safe_is_latched_until_arm() -> None:
    emu, wire = _armed_emulator()
    emu.run_ticks(1000)  # no host frames: the watchdog trips
    assert emu.renderer.state == DeviceState.SAFE
    for message in (*SLAB.upload_messages(), Heartbeat()):
        wire.send(message)  # DISARM, a new table, heartbeats: still safe
    from ctdrill.haptics.protocol import Disarm

    wire.send(Disarm())
    wire.hello()
    emu.run_ticks(100)
    assert emu.renderer.state == DeviceState.SAFE
    for m in SLAB.upload_messages():
        wire.send(m)
    wire.send(Arm(SLAB.crc32))
    emu.run_ticks(10)
    assert emu.renderer.state == DeviceState.CUTTING and emu.renderer.faults == 0


# ---------------------------------------------------------------- the host side, in-process


class _LyingEmulator(DeviceEmulator):
    """A device whose telemetry reports the drill wherever the hand is (no stop)."""

    def _send(self, message: Message, *, session: int | None = None) -> None:
        if isinstance(message, Telemetry):
            message = Telemetry(
                message.tick,
                message.master_mm,
                max(message.drill_mm, message.master_mm),
                message.velocity_mm_s,
                message.force_cmd_n,
                message.force_est_n,
                message.state,
                message.faults,
                message.overruns,
                message.table_crc32,
            )
        super()._send(message, session=session)


class _BrokenLink(SimLink):
    """A link whose writes fail from device time ``fail_s`` on (an unplugged adapter)."""

    def __init__(self, emulator: DeviceEmulator, fail_s: float) -> None:
        super().__init__(emulator)
        self.fail_s = fail_s

    def write(self, data: bytes) -> None:
        if self.emulator.now_s >= self.fail_s:
            raise DeviceError("writing to sim failed: [Errno 5] Input/output error")
        super().write(data)


def _with_device(monkeypatch: pytest.MonkeyPatch, device: HostDevice) -> None:
    monkeypatch.setattr("ctdrill.app.rehearse.open_device", lambda spec, seed=0: device)


def test_a_device_lying_past_the_stop_ends_with_stop_and_exit_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    emu = _LyingEmulator(nonce_seed=0)
    _with_device(monkeypatch, HostDevice(SimLink(emu), token_seed=0))
    out = tmp_path / "out"
    assert main(_args78(out)) == 3
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"].startswith("drill_past_stop")
    host = summary["faults"][-1]
    assert host["stop_acknowledged"] and host["disarm_acknowledged"]
    assert emu.renderer.state == DeviceState.SAFE and emu.renderer.faults & Fault.HOST_STOP
    assert "error: the session ended early (drill_past_stop" in capsys.readouterr().err


def _args78(out: Path) -> list[str]:
    args = _rehearse_args(out, duration="3")
    args[args.index("push:20")] = "push:78"
    return args


def test_the_hosts_own_write_error_ends_with_exit_3_and_a_summary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    emu = DeviceEmulator(nonce_seed=0)
    _with_device(monkeypatch, HostDevice(_BrokenLink(emu, fail_s=0.3), token_seed=0))
    out = tmp_path / "out"
    assert main(_rehearse_args(out)) == 3
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"].startswith("host_error: writing")
    host = summary["faults"][-1]
    assert host["stop_acknowledged"] is False and "Input/output error" in host["stop_error"]
    assert summary["samples"] > 0


# ---------------------------------------------------------------- over a real pty


#: Device time the pty cases watch after the host left: 4 watchdog periods (on a loaded
#: machine the emulator's clock may lag the wall clock; the checks are in device time).
AFTER_TICKS = 2000


def _host_process(out: Path, link: Path, duration: str = "5") -> subprocess.Popen[str]:
    """``ctdrill rehearse`` on the serial device at ``link``, writing ``out``."""
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "ctdrill.app.cli",
            *_rehearse_args(out, duration=duration),
            "--device",
            f"serial:{link}",
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _wait_armed_host(out: Path, host: subprocess.Popen[str]) -> None:
    """:func:`_wait_armed`; a host that ended first on a watchdog trip its own heartbeat gap
    explains (a loaded machine) raises :class:`HostLate` (the case is run again)."""
    try:
        _wait_armed(out)
    except AssertionError:
        host.wait(timeout=20)
        summary = out / "summary.json"
        if summary.is_file():
            _raise_if_host_late(json.loads(summary.read_text()))
        raise


def _raise_if_host_late(summary: dict[str, object]) -> None:
    reason = str(summary.get("reason") or "")
    gap = float(summary.get("max_heartbeat_gap_s") or 0.0)  # type: ignore[arg-type]
    if host_late("raised watchdog" in reason, gap):
        raise HostLate(f"{reason} (host heartbeat gap {gap * 1e3:.0f} ms)")


@pytest.mark.timeout(180)
def test_a_looped_back_pty_line_never_keeps_the_device_rendering(tmp_path: Path) -> None:
    def case(link: Path, proc: subprocess.Popen[str]) -> None:
        dev = SerialDevice(str(link))
        try:
            _armed_pushing(dev, 3000)
            port = dev.transport.port  # the host is gone; its port echoes the device
            seen = b""
            end = time.monotonic() + 20.0
            tel: list[Telemetry] = []
            while time.monotonic() < end and not _safe_for(tel, AFTER_TICKS):
                data = port.read(port.in_waiting or 1)
                port.write(data)
                seen += data
                tel = _telemetry(seen)
        finally:
            dev.close()
        assert proc.poll() is None
        # it went safe on its watchdog and 200 ms of its own echoed frames never re-armed it
        assert _safe_for(tel, AFTER_TICKS) and tel[-1].faults & Fault.WATCHDOG

    with_fresh_emulator(tmp_path, case)


def _raw(s: TelemetrySample) -> Telemetry:
    return Telemetry(
        s.tick,
        s.master_mm,
        s.drill_mm,
        s.velocity_mm_s,
        s.force_cmd_n,
        s.force_est_n,
        s.state,
        s.faults,
        s.overruns,
        s.table_crc32,
    )


def _safe_for(tel: list[Telemetry], ticks: int) -> bool:
    """The device went safe and stayed safe with zero force for ``ticks`` since."""
    first = next((i for i, t in enumerate(tel) if t.state == DeviceState.SAFE), None)
    if first is None:
        return False
    after = tel[first:]
    assert all(t.state == DeviceState.SAFE and t.force_cmd_n == 0.0 for t in after), after[-1]
    return after[-1].tick - after[0].tick >= ticks


@pytest.mark.timeout(180)
def test_a_replayed_heartbeat_over_a_pty_does_not_keep_it_armed(tmp_path: Path) -> None:
    def case(link: Path, _proc: subprocess.Popen[str]) -> None:
        dev = SerialDevice(str(link))
        try:
            _armed_pushing(dev, 3000)
            beat = encode(Heartbeat(), seq=dev._seq, session=dev.session)  # the last one sent
            tel = dev.poll()
            first = tel[-1].tick if tel else 0
            end = time.monotonic() + 20.0
            raw = [_raw(t) for t in tel]
            while time.monotonic() < end and not _safe_for(raw, AFTER_TICKS):
                dev.write_raw(beat)  # the same 24 bytes every 10 ms
                dev.wait(0.01)
                raw += [_raw(t) for t in dev.poll()]
        finally:
            dev.close()
        assert _safe_for(raw, AFTER_TICKS) and raw[-1].tick > first
        assert raw[-1].faults & Fault.WATCHDOG
        assert any(n.reason == NakReason.STALE_SEQUENCE for n in dev.naks)

    with_fresh_emulator(tmp_path, case)


@pytest.mark.timeout(180)
def test_a_frozen_device_ends_the_rehearsal_with_exit_3(tmp_path: Path) -> None:
    def case(link: Path, emu: subprocess.Popen[str]) -> None:
        out = link.with_name(f"{link.name}-out")
        host = _host_process(out, link)
        _wait_armed_host(out, host)
        os.kill(emu.pid, signal.SIGSTOP)
        try:
            _, err = host.communicate(timeout=20)
        finally:
            os.kill(emu.pid, signal.SIGCONT)
        summary = json.loads((out / "summary.json").read_text())
        _raise_if_host_late(summary)  # tripped before the freeze: a loaded machine, run again
        assert host.returncode == 3, err
        assert summary["complete"] is False and summary["reason"].startswith("telemetry_silent")
        assert summary["faults"][-1]["stop_acknowledged"] is False  # frozen: nobody answered
        assert err.startswith("error: the session ended early (telemetry_silent")

    with_fresh_emulator(tmp_path, case)


@pytest.mark.timeout(180)
def test_a_killed_device_ends_the_rehearsal_with_exit_3(tmp_path: Path) -> None:
    def case(link: Path, emu: subprocess.Popen[str]) -> None:
        out = link.with_name(f"{link.name}-out")
        host = _host_process(out, link)
        _wait_armed_host(out, host)
        emu.kill()
        _, err = host.communicate(timeout=20)
        assert host.returncode == 3, err
        summary = json.loads((out / "summary.json").read_text())
        assert summary["complete"] is False and summary["outcome"] == "fault"
        assert summary["faults"][-1]["source"] == "host"

    with_fresh_emulator(tmp_path, case, killed=True)


@pytest.mark.timeout(180)
def test_a_killed_host_leaves_no_force_and_the_previous_session(tmp_path: Path) -> None:
    def case(link: Path, _proc: subprocess.Popen[str]) -> None:
        out = link.with_name(f"{link.name}-out")
        assert main(_rehearse_args(out, duration="0.2")) == 0
        before = {p.name: p.read_bytes() for p in out.iterdir()}
        host = _host_process(out, link)
        _wait_armed_host(out, host)
        host.kill()
        host.wait(timeout=10)
        dev = SerialDevice(str(link))  # read the device's own telemetry, no HELLO
        try:
            # until it has been safe for AFTER_TICKS of device time (the watchdog's 50 ms and
            # more, however slowly a loaded host runs the emulator)
            seen, tel = b"", []
            end = time.monotonic() + 20.0
            while time.monotonic() < end and not _safe_for(tel, AFTER_TICKS):
                dev.wait(0.01)
                seen += dev.transport.read()
                tel = _telemetry(seen)
        finally:
            dev.close()
        assert _safe_for(tel, AFTER_TICKS)  # every sample since the first safe one: no force
        assert tel[-1].faults & Fault.WATCHDOG
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # untouched

    with_fresh_emulator(tmp_path, case)
