"""The rules protocol version 3 added, on the emulator and the host (docs/protocol.md section 2):
ARM names a table of the current session, sequence numbers wrap, STOP and DISARM work from any
host, a host frame has no free header bytes, and a forged frame can only make the device safer.
"""

from __future__ import annotations

import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import (
    HOST_TYPES,
    Ack,
    Arm,
    DeviceState,
    Disarm,
    Fault,
    FrameReader,
    Heartbeat,
    Hello,
    Message,
    Nak,
    NakReason,
    Packet,
    ProfileBegin,
    SimOperator,
    SimReset,
    Stop,
    Telemetry,
    cobs_decode,
    cobs_encode,
    crc32c,
    encode,
    seq_after,
)
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import parse_operator
from ctdrill.haptics.sim import SimLink
from tests.haptics.wire import Wire

SLAB = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=20.0)
OTHER = ProfileTable.slab(s0_n=6.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=20.0)


def _uploaded(table: ProfileTable = SLAB, *, first_seq: int = 0) -> tuple[DeviceEmulator, Wire]:
    emu = DeviceEmulator(nonce_seed=3)
    wire = Wire(emu)
    wire.seq = first_seq  # the HELLO's is the next
    wire.hello()
    for m in table.upload_messages():
        wire.send(m)
    wire.packets()
    return emu, wire


def _replies(wire: Wire) -> list[Message]:
    return [p.message for p in wire.packets() if not isinstance(p.message, Telemetry)]


# ---------------------------------------------------------------- ARM names the table


def test_arm_needs_the_table_of_this_session_and_names_it() -> None:
    emu, wire = _uploaded()
    wire.send(Arm(OTHER.crc32))  # another table
    assert _replies(wire) == [Nak(0x20, wire.seq, NakReason.PROFILE_CRC)]
    emu.run_ticks(10)
    tel = [p.message for p in wire.packets() if isinstance(p.message, Telemetry)]
    assert tel[-1].table_crc32 == SLAB.crc32  # TELEMETRY names the table held
    wire.hello()  # a new session: the table stays loaded, but it is not this session's
    wire.send(Arm(SLAB.crc32))
    assert _replies(wire) == [Nak(0x20, wire.seq, NakReason.NOT_READY)]
    assert emu.renderer.state == DeviceState.IDLE
    for m in SLAB.upload_messages():
        wire.send(m)
    wire.send(Arm(SLAB.crc32))
    assert _replies(wire)[-1] == Ack(0x20, wire.seq)
    assert emu.renderer.state == DeviceState.CUTTING
    wire.send(ProfileBegin(*SLAB.begin_message().__dict__.values()))  # a new upload begins
    emu.run_ticks(10)
    tel = [p.message for p in wire.packets() if isinstance(p.message, Telemetry)]
    assert tel[-1].table_crc32 == 0 and tel[-1].state == DeviceState.IDLE


# ---------------------------------------------------------------- sequence numbers


@settings(max_examples=40)
@given(st.integers(0, 2**32 - 1))
def test_a_hello_at_any_seq_leaves_a_session_that_accepts_the_next_frame(seq: int) -> None:
    emu = DeviceEmulator(nonce_seed=1)
    emu.receive(encode(Hello(host_token=7), seq=seq))
    session = emu.session
    emu.take_output()
    nxt = (seq + 1) & 0xFFFFFFFF
    for stale in (seq, (seq - 1) & 0xFFFFFFFF, (seq + 2**31) & 0xFFFFFFFF):
        emu.receive(encode(Heartbeat(), seq=stale, session=session))
    emu.receive(encode(Arm(SLAB.crc32), seq=nxt, session=session))
    naks = [p.message for p in FrameReader().feed(emu.take_output()) if isinstance(p, Packet)]
    assert [n.reason for n in naks if isinstance(n, Nak)] == [
        NakReason.STALE_SEQUENCE,
        NakReason.STALE_SEQUENCE,
        NakReason.STALE_SEQUENCE,
        NakReason.NOT_READY,  # the ARM was accepted and handled: no table yet
    ]
    assert emu.host_seq == nxt


def test_a_session_runs_through_the_wrap_of_both_counters() -> None:
    emu = DeviceEmulator(nonce_seed=2)
    emu._seq = 2**32 - 40  # the device's counter wraps 40 frames in (during the upload)
    dev = HostDevice(SimLink(emu), token_seed=2)
    dev._seq = 2**32 - 20  # the host's wraps during the upload too
    result = run_session(dev, SLAB, parse_operator("push:10"), 0.3)
    assert result.complete, result.reason
    assert result.samples >= 290 and dev.rejected_frames == 0
    assert emu._seq < 1000 and dev._seq < 1000  # both wrapped


# ---------------------------------------------------------------- STOP and DISARM from any host


@pytest.mark.parametrize("how", ["another session", "no session", "stale seq", "replayed"])
@pytest.mark.parametrize("command", [Stop(), Disarm()])
def test_stop_and_disarm_work_from_any_host(how: str, command: Stop | Disarm) -> None:
    emu, wire = _uploaded()
    wire.send(Arm(SLAB.crc32))
    wire.send(SimOperator(1, 10.0))
    emu.run_ticks(100)
    wire.packets()
    session, seq = {
        "another session": (wire.session ^ 0x5A5A, 10**6),
        "no session": (0, 1),
        "stale seq": (wire.session, 1),
        "replayed": (wire.session, wire.seq),
    }[how]
    emu.receive(encode(command, seq=seq, session=session))
    frames = [p for p in FrameReader().feed(emu.take_output()) if isinstance(p, Packet)]
    ack = next(p for p in frames if isinstance(p.message, Ack))
    assert ack.message == Ack(int(command.TYPE), seq) and ack.session == session
    if isinstance(command, Stop):
        assert emu.renderer.state == DeviceState.SAFE and emu.renderer.faults & Fault.HOST_STOP
    else:
        assert emu.renderer.state == DeviceState.IDLE
    assert emu.renderer.force_cmd_n == 0.0
    assert emu.host_seq == wire.seq  # the session's sequence did not move


# ---------------------------------------------------------------- no free header bytes


@pytest.mark.parametrize("mtype", sorted(HOST_TYPES))
def test_a_host_frame_with_a_clock_is_refused(mtype: int) -> None:
    emu, wire = _uploaded()
    messages: dict[int, Message] = {
        int(m.TYPE): m
        for m in (
            Hello(host_token=1),
            *SLAB.upload_messages(),
            Arm(SLAB.crc32),
            Disarm(),
            Heartbeat(),
            Stop(),
            SimOperator(1, 5.0),
            SimReset(),
        )
    }
    before = emu.session
    emu.receive(encode(messages[mtype], seq=wire.seq + 1, session=wire.session, time_us=1))
    assert _replies(wire) == [Nak(mtype, wire.seq + 1, NakReason.BAD_HEADER)]
    assert emu.session == before and emu.renderer.state == DeviceState.IDLE


def _forged(stop_frame: bytes, field: slice, fmt: str) -> bytes:
    """The STOP rewritten into a HEARTBEAT, its CRC-32C kept valid by choosing ``field``."""
    raw = bytearray(cobs_decode(stop_frame[:-1]))
    want = crc32c(bytes(raw[:-4]))
    raw[1] = 0x22
    body = raw[:-4]

    def crc_with(value: int) -> int:
        b = bytearray(body)
        b[field] = struct.pack(fmt, value)
        return crc32c(bytes(b))

    base = crc_with(0)
    width = struct.calcsize(fmt) * 8
    basis: dict[int, tuple[int, int]] = {}  # GF(2) elimination: bit -> (syndrome, choice)
    for k in range(width):
        v, comb = crc_with(1 << k) ^ base, 1 << k
        for bit in sorted(basis, reverse=True):
            if v >> bit & 1:
                v, comb = v ^ basis[bit][0], comb ^ basis[bit][1]
        if v:
            basis[v.bit_length() - 1] = (v, comb)
    v, choice = want ^ base, 0
    for bit in sorted(basis, reverse=True):
        if v >> bit & 1:
            v, choice = v ^ basis[bit][0], choice ^ basis[bit][1]
    assert v == 0
    body[field] = struct.pack(fmt, choice)
    return cobs_encode(bytes(body) + struct.pack("<I", want)) + b"\x00"


def test_a_forged_time_us_is_refused() -> None:
    # Version 2's forgery: a STOP rewritten into a HEARTBEAT, the check fixed through time_us.
    emu, wire = _uploaded()
    wire.send(Arm(SLAB.crc32))
    wire.packets()
    stop = wire.frame(Stop())
    emu.receive(_forged(stop, slice(10, 18), "<Q"))
    assert _replies(wire) == [Nak(0x22, wire.seq, NakReason.BAD_HEADER)]
    emu.receive(stop)  # the STOP itself is obeyed
    assert emu.renderer.state == DeviceState.SAFE


@pytest.mark.parametrize("accepted", [True, False])
def test_a_forged_sequence_only_makes_the_device_safer(accepted: bool) -> None:
    # Fixed through the sequence number instead (its only free bits), the forged HEARTBEAT
    # carries a seq the forger cannot choose: the CRC is linear, so it is the STOP's seq XOR a
    # constant of the two types. Where that comes after the session's last seq, the forgery is
    # accepted, the real host's next frames are stale and the device trips its watchdog 50 ms
    # after it; where it does not (ctdrill's sessions start at seq 1: always), it is refused and
    # the STOP is lost, and the host, seeing no acknowledgement, sends it again: obeyed, whatever
    # its seq.
    for first in range(0, 2**32, 2**28):  # sessions whose forgery falls either way
        emu, wire = _uploaded(first_seq=first)
        wire.send(Arm(SLAB.crc32))
        wire.packets()
        stop, stop_seq = wire.frame(Stop()), wire.seq
        forged = _forged(stop, slice(2, 6), "<I")
        (packet,) = FrameReader().feed(forged)
        assert isinstance(packet, Packet) and packet.message == Heartbeat()
        if seq_after(packet.seq, wire.seq - 1) == accepted:
            break
    else:
        raise AssertionError("no session's forgery fell that way")
    emu.receive(forged)
    forged_at = emu.now_s
    if accepted:
        for _ in range(10):  # the real host beats on, in vain
            wire.send(Heartbeat())
            emu.run_ticks(100)
        assert emu.renderer.state == DeviceState.SAFE and emu.renderer.faults & Fault.WATCHDOG
        assert emu.renderer.safe_since_s - forged_at <= 0.050 + 1e-4
    else:
        assert _replies(wire) == [Nak(0x22, packet.seq, NakReason.STALE_SEQUENCE)]
        assert emu.renderer.state == DeviceState.CUTTING
    emu.receive(stop)  # the host did not see its STOP acknowledged: it sends it again
    assert Ack(0x23, stop_seq) in _replies(wire)
    assert emu.renderer.state == DeviceState.SAFE and emu.renderer.faults & Fault.HOST_STOP
