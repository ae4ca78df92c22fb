"""The simulated device end to end: protocol, renderer, force controller, plant and hand."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.haptics.device import DeviceError
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import (
    Arm,
    DeviceState,
    Fault,
    FrameReader,
    Nak,
    NakReason,
    OperatorKind,
    Packet,
    ProfileBegin,
    ProfileChunk,
    ProfileEnd,
    Telemetry,
    cobs_decode,
    cobs_encode,
    crc32c,
)
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import parse_operator
from ctdrill.haptics.sim import SimulatedDevice
from tests.haptics.wire import Wire


def _connected(table: ProfileTable) -> SimulatedDevice:
    dev = SimulatedDevice()
    info = dev.hello()
    assert info.version.tick_rate_hz == 10_000
    assert info.limits.peak_force_n == 78.0 and info.limits.continuous_force_n == 20.0
    assert info.limits.watchdog_ms == 50
    dev.upload_profile(table)
    return dev


@pytest.mark.parametrize(("force_n", "s0_n"), [(6.0, 4.0), (20.0, 8.0)])
def test_constant_push_on_a_slab_gives_the_model_feed(force_n: float, s0_n: float) -> None:
    # Through the whole loop (DOB/RFOB force control, Coulomb friction, encoder): a constant
    # hand force F on a homogeneous slab cuts at v = (F/S0 - 1)/Ke and renders F.
    table = ProfileTable.slab(s0_n=s0_n, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=38.0)
    rows: list[tuple[float, float, float, float, str]] = []
    run_session(SimulatedDevice(), table, parse_operator(f"push:{force_n}"), 3.0, sink=rows.extend)
    steady = [r for r in rows if 2.0 <= r[0] <= 3.0]
    feed = (steady[-1][2] - steady[0][2]) / (steady[-1][0] - steady[0][0])
    assert feed == pytest.approx((force_n / s0_n - 1.0) / 0.25, rel=0.01)
    mean_force = sum(r[3] for r in steady) / len(steady)
    assert mean_force == pytest.approx(force_n, abs=0.02)
    assert all(r[4] == "cutting" for r in steady)


def test_below_s0_the_drill_holds_within_coulomb_friction() -> None:
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=38.0)
    rows: list[tuple[float, float, float, float, str]] = []
    run_session(SimulatedDevice(), table, parse_operator("push:3"), 1.0, sink=rows.extend)
    assert rows[-1][2] == pytest.approx(rows[len(rows) // 2][2], abs=1e-6)  # no cutting
    assert rows[-1][3] == pytest.approx(3.0, abs=1.0)  # the device's Coulomb friction is 1 N


@settings(max_examples=20)
@given(
    force=st.floats(0.0, 78.0),
    layers=st.lists(st.floats(0.0, 40.0), min_size=1, max_size=12),
    vib=st.floats(0.0, 5.0),
    ke=st.floats(0.0, 1.0),
    step=st.sampled_from([0.05, 0.25, 0.5]),
    stop=st.floats(0.0, 6.0),
)
def test_drill_never_passes_the_stop_depth(
    force: float, layers: list[float], vib: float, ke: float, step: float, stop: float
) -> None:
    # Any heterogeneous profile: layers of 0.5 mm with their own S0 (air to dense bone), any
    # vibration, any Ke, any hand force up to the device's peak.
    s0 = np.repeat(np.array(layers), max(1, round(0.5 / step)))
    table = ProfileTable(
        depth_step_mm=step,
        s0_n=s0,
        s1_n=vib * np.ones_like(s0),
        s2_n=-0.5 * vib * np.ones_like(s0),
        ke_per_mm_s=ke,
        freqs_hz=np.array([30.0, 60.0]),
        stop_depth_mm=stop,
    )
    rows: list[tuple[float, float, float, float, str]] = []
    result = run_session(
        SimulatedDevice(), table, parse_operator(f"push:{force}"), 0.5, sink=rows.extend
    )
    assert result.max_drill_mm <= table.stop_depth_mm
    # within the peak; only the release damper pulls (a master moving back), at most 20 N
    assert all(math.isfinite(r[3]) and -20.0 <= r[3] <= 78.0 for r in rows)
    assert result.final_state in ("cutting", "stopped")


@settings(max_examples=50)
@given(st.lists(st.binary(max_size=300), max_size=8))
def test_random_bytes_never_crash_or_arm_the_device(chunks: list[bytes]) -> None:
    emu = DeviceEmulator(nonce_seed=1)
    wire = Wire(emu)
    wire.hello()
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=3.0, stop_depth_mm=2.0)
    for m in table.upload_messages():
        wire.send(m)
    for chunk in chunks:
        emu.receive(chunk)
        emu.run_ticks(10)
    assert emu.renderer.state == DeviceState.IDLE
    for item in FrameReader().feed(emu.take_output()):
        assert isinstance(item, Packet)  # the device only ever writes valid frames


def test_feed_operator_cuts_at_its_feed_and_stops() -> None:
    # A hand moving at 2 mm/s: the front holds until the coupling carries S0 (4 / 11 mm), then
    # settles at the hand's feed with the force S0 (1 + Ke v) = 6 N; the drill stops at 5 mm
    # (the hand's spring lags 6 N / 5 N/mm and the coupling 6 / 11 mm: after about 3.4 s).
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=5.0)
    rows: list[tuple[float, float, float, float, str]] = []
    result = run_session(SimulatedDevice(), table, parse_operator("feed:2"), 4.6, sink=rows.extend)
    steady = [r for r in rows if 2.0 <= r[0] <= 3.0]
    feed = (steady[-1][2] - steady[0][2]) / (steady[-1][0] - steady[0][0])
    assert feed == pytest.approx(2.0, rel=0.02)
    assert steady[-1][3] == pytest.approx(6.0, abs=0.05)
    assert result.max_drill_mm == pytest.approx(5.0, abs=1e-6)
    assert rows[-1][4] == "stopped"


def test_watchdog_trips_within_50_ms_of_the_last_host_frame() -> None:
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=10.0)
    dev = _connected(table)
    dev.arm()
    for _ in range(30):
        dev.heartbeat()
        dev.set_operator(int(OperatorKind.PUSH), 8.0)
        dev.wait(0.01)
    last_frame_s = dev.clock_s()
    dev.heartbeat()
    dev.wait(0.2)  # the link is lost: nothing more is sent
    samples = dev.poll()
    safe = [s for s in samples if s.state == DeviceState.SAFE]
    assert safe and safe[-1].force_cmd_n == 0.0 and safe[-1].faults & Fault.WATCHDOG
    trips = [t for t, f in dev.fault_reports if f.faults & Fault.WATCHDOG]
    assert len(trips) == 1
    assert 0.050 - 1e-9 <= trips[0] - last_frame_s <= 0.050 + 1e-4 + 1e-9
    # Latched: heartbeats do not clear it, the drill does not advance; ARM does, once the
    # handle is retracted (the hand kept pushing 8 N into the unpowered master).
    drill = safe[-1].drill_mm
    dev.heartbeat()
    dev.wait(0.05)
    assert all(s.state == DeviceState.SAFE and s.drill_mm <= drill for s in dev.poll())
    with pytest.raises(DeviceError, match="NOT_RETRACTED"):
        dev.arm()
    for _ in range(30):
        dev.heartbeat()
        dev.set_operator(int(OperatorKind.PUSH), -5.0)
        dev.wait(0.01)
    dev.arm()
    dev.heartbeat()
    dev.wait(0.02)
    assert dev.poll()[-1].state == DeviceState.CUTTING


def test_device_refuses_bad_uploads_and_arming_without_a_table() -> None:
    dev = SimulatedDevice()
    dev.hello()
    with pytest.raises(DeviceError, match="refused ARM \\(NOT_READY\\)"):
        dev.arm()
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=3.0, stop_depth_mm=2.0)
    messages = list(table.upload_messages())
    begin, chunks, end = messages[0], messages[1:-1], messages[-1]
    assert isinstance(end, ProfileEnd)
    dev.command(begin)
    for chunk in chunks:
        dev.command(chunk)
    with pytest.raises(DeviceError, match="PROFILE_CRC"):
        dev.command(ProfileEnd(end.n_steps, end.crc32 ^ 1))
    with pytest.raises(DeviceError, match="NOT_READY"):
        dev.arm()
    dev.command(begin)
    with pytest.raises(DeviceError, match="PROFILE_ORDER"):
        dev.command(ProfileChunk(16, ((1.0, 0.0, 0.0),)))
    dev.command(begin)
    with pytest.raises(DeviceError, match="NONFINITE"):
        dev.command(ProfileChunk(0, ((math.nan, 0.0, 0.0),)))
    with pytest.raises(DeviceError, match="NONFINITE"):
        dev.command(ProfileBegin(10, 0.05, math.inf, 30.0, 60.0, 1.0))
    with pytest.raises(DeviceError, match="BAD_VALUE"):
        dev.command(ProfileBegin(10, -0.05, 0.25, 30.0, 60.0, 1.0))
    dev.upload_profile(table)
    dev.arm()


def test_garbage_and_corrupt_frames_are_refused_without_effect() -> None:
    emu = DeviceEmulator(nonce_seed=1)
    wire = Wire(emu)
    wire.hello()
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=3.0, stop_depth_mm=2.0)
    for m in table.upload_messages():
        wire.send(m)
    wire.packets()
    arm = bytearray(cobs_decode(wire.frame(Arm(table.crc32))[:-1]))
    arm[-1] ^= 0xFF  # corrupt CRC: must not arm
    emu.receive(cobs_encode(bytes(arm)) + b"\x00")
    emu.receive(bytes(range(256)) * 3 + b"\x00")
    raw = bytearray(cobs_decode(wire.frame(Arm(table.crc32))[:-1]))
    raw[1] = 0x23  # STOP's type with a 5-byte body: wrong length
    raw[-4:-4] = b"\x07"
    raw[-4:] = struct.pack("<I", crc32c(bytes(raw[:-4])))
    emu.receive(cobs_encode(bytes(raw)) + b"\x00")
    # a valid TELEMETRY frame sent to the device: wrong direction, dropped without a reply
    emu.receive(wire.frame(Telemetry(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0, 0)))
    emu.run_ticks(100)
    assert emu.renderer.state == DeviceState.IDLE
    naks = [p.message for p in wire.packets() if isinstance(p.message, Nak)]
    assert naks[0] == Nak(0, 0, NakReason.BAD_FRAME)  # the corrupt ARM
    assert Nak(0x23, wire.seq - 1, NakReason.BAD_LENGTH) in naks  # header echoed
    assert not any(n.acked_type == 0x30 for n in naks)
    assert emu.frames_rejected >= 4


def test_reset_loses_the_table_and_reports_it() -> None:
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=10.0)
    dev = _connected(table)
    dev.arm()
    dev.heartbeat()
    dev.wait(0.02)
    assert dev.poll()[-1].faults & Fault.RESET == 0
    dev.sim_reset()
    dev.wait(0.02)
    assert dev.poll() == [] and dev.lost_session()  # its telemetry no longer has our session
    state = dev.emulator.renderer
    assert state.state == DeviceState.IDLE and not state.has_profile
    with pytest.raises(DeviceError, match="BAD_SESSION"):
        dev.arm()
    dev.hello()  # a new session: the table is gone
    with pytest.raises(DeviceError, match="NOT_READY"):
        dev.arm()
    dev.wait(0.02)
    assert dev.poll()[-1].faults & Fault.RESET
