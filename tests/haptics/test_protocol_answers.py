"""docs/protocol.md section 8: each answer to a client's question, encoded against the
emulator and ctdrill's host (issue 36)."""

from __future__ import annotations

import dataclasses
import random
from pathlib import Path

import pytest

from ctdrill.haptics.codes import MsgType, NakReason
from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.protocol import (
    Ack,
    Disarm,
    FrameReader,
    Heartbeat,
    Hello,
    Limits,
    Nak,
    Packet,
    ProfileEnd,
    SimOperator,
    Stop,
    Version,
    encode,
)
from ctdrill.haptics.watch import CLOCK_RATE_TOLERANCE, CLOCK_SLACK_S, TelemetryWatch

ROOT = Path(__file__).resolve().parents[2]


def _replies(emu: DeviceEmulator, frame: bytes) -> list[Packet]:
    emu.receive(frame)
    out = [p for p in FrameReader().feed(emu.take_output()) if isinstance(p, Packet)]
    return out


def _hello(emu: DeviceEmulator, token: int = 0xBEEF) -> int:
    """A session on ``emu``; its nonce."""
    version, limits = _replies(emu, encode(Hello(3, token), seq=1))
    assert isinstance(version.message, Version) and isinstance(limits.message, Limits)
    return version.session


def test_the_document_has_the_seven_answers() -> None:
    text = (ROOT / "docs" / "protocol.md").read_text(encoding="utf-8")
    section = text[text.index("## 8. Answers to a client's questions") :]
    for n in range(1, 8):
        assert f"\n{n}. **" in section
    assert "LIMITS carries no token" in text[: text.index("## 2. Messages")]


# 1. LIMITS carries no token: the device's next frame in VERSION's session
def test_limits_has_no_token_and_follows_version_in_its_session() -> None:
    assert [f.name for f in dataclasses.fields(Limits)] == [
        "peak_force_n",
        "continuous_force_n",
        "thermal_budget_n2_s",
        "watchdog_ms",
        "max_profile_steps",
        "travel_min_mm",
        "travel_max_mm",
    ]
    emu = DeviceEmulator(nonce_seed=3)
    version, limits = _replies(emu, encode(Hello(3, 0x1234), seq=7))
    assert isinstance(version.message, Version) and version.message.host_token == 0x1234
    assert limits.session == version.session != 0 and limits.seq == version.seq + 1


class _Link:
    """Scripted device bytes, delivered once the host has written its HELLO."""

    name = "answers"

    def __init__(self) -> None:
        self.pending = b""
        self.written = b""
        self.now = 0.0

    def write(self, data: bytes) -> None:
        self.written += data

    def read(self) -> bytes:
        if not self.written:
            return b""
        data, self.pending = self.pending, b""
        return data

    def wait(self, duration_s: float) -> None:
        self.now += duration_s

    def clock_s(self) -> float:
        return self.now

    def close(self) -> None:
        pass


def test_the_host_takes_the_limits_of_its_versions_session_only() -> None:
    token = random.Random(5).randrange(1 << 32)  # the host's token, seeded
    good = Limits(60.0, 15.0, 3000.0, 40, 2048, -10.0, 50.0)
    stray = dataclasses.replace(good, watchdog_ms=65535)  # outside the host's bounds
    link = _Link()
    link.pending = (
        encode(Version(3, 0, 1, 0, 10_000, token), seq=20, session=0xAA)
        + encode(stray, seq=21, session=0xBB)  # another session's LIMITS: dropped
        + encode(stray, seq=20, session=0xAA)  # not after VERSION's seq: dropped
        + encode(good, seq=22, session=0xAA)
    )
    info = HostDevice(link, token_seed=5, timeout_s=0.05).hello()
    assert info.limits == good


# 2. The order of the refusals: the first check that fails decides
def _nak(packets: list[Packet]) -> tuple[int, int, int] | None:
    (p,) = packets
    assert isinstance(p.message, Nak)
    return p.message.acked_type, p.message.acked_seq, p.message.reason


def test_refusals_apply_in_the_documented_order() -> None:
    emu = DeviceEmulator(nonce_seed=0)
    session = _hello(emu)
    # time_us and the session both wrong: BAD_HEADER (step 5 before step 7)
    packet = encode(Heartbeat(), seq=3, session=0, time_us=5)
    assert _nak(_replies(emu, packet)) == (MsgType.HEARTBEAT, 3, NakReason.BAD_HEADER)
    # another session and a stale seq: BAD_SESSION (the session before the seq)
    stale_other = encode(Heartbeat(), seq=1, session=session ^ 1)
    assert _nak(_replies(emu, stale_other)) == (MsgType.HEARTBEAT, 1, NakReason.BAD_SESSION)
    # the current session and a stale seq: STALE_SEQUENCE
    stale = encode(Heartbeat(), seq=1, session=session)
    assert _nak(_replies(emu, stale)) == (MsgType.HEARTBEAT, 1, NakReason.STALE_SEQUENCE)
    # a HELLO asking for version 2 with time_us set: BAD_HEADER (step 5 before step 6)
    hello2 = encode(Hello(2, 1), seq=9, time_us=1)
    assert _nak(_replies(emu, hello2)) == (MsgType.HELLO, 9, NakReason.BAD_HEADER)
    # a device->host type is dropped whatever else is wrong with it (step 3)
    assert _replies(emu, encode(Ack(0x20, 1), seq=4, session=0, time_us=7)) == []
    # in the session and in sequence: the command's own check (step 8)
    end = encode(ProfileEnd(1, 0), seq=5, session=session)
    assert _nak(_replies(emu, end)) == (MsgType.PROFILE_END, 5, NakReason.PROFILE_ORDER)


def test_an_undefined_type_is_refused_before_its_header_fields() -> None:
    emu = DeviceEmulator(nonce_seed=0)
    _hello(emu)
    good = bytearray(encode(Heartbeat(), seq=2, session=0, time_us=123))
    # rewrite the type byte to 0x2A (undefined), keep the CRC valid by re-encoding by hand
    from ctdrill.haptics.framing import cobs_decode, cobs_encode, crc32c

    raw = bytearray(cobs_decode(bytes(good[:-1])))
    raw[1] = 0x2A
    body = bytes(raw[:-4])
    frame = cobs_encode(body + crc32c(body).to_bytes(4, "little")) + b"\0"
    assert _nak(_replies(emu, frame)) == (0x2A, 2, NakReason.UNKNOWN_TYPE)


# 3. and 4. STOP and DISARM from another session: time_us 0, their ACK in their session
def test_a_stop_from_another_session_needs_time_us_0_and_is_acked_in_its_session() -> None:
    emu = DeviceEmulator(nonce_seed=1)
    old = _hello(emu)
    current = _hello(emu, token=0xCAFE)
    assert current != old
    refused = _replies(emu, encode(Stop(), seq=40, session=old, time_us=1))
    assert _nak(refused) == (MsgType.STOP, 40, NakReason.BAD_HEADER)
    assert refused[0].session == current  # a refusal comes in the current session
    assert emu.renderer.state != 3  # not obeyed
    answers = _replies(emu, encode(Stop(), seq=41, session=old))
    ack = answers[0]
    assert isinstance(ack.message, Ack) and ack.session == old
    assert (ack.message.acked_type, ack.message.acked_seq) == (MsgType.STOP, 41)
    assert emu.renderer.state == 3  # obeyed: safe
    fault = answers[1]
    assert fault.session == current  # the FAULT report goes to the current session
    # a DISARM before any HELLO: acknowledged in session 0, naming its type and seq
    (ack0,) = _replies(DeviceEmulator(nonce_seed=2), encode(Disarm(), seq=3, session=0))
    assert isinstance(ack0.message, Ack) and ack0.session == 0
    assert (ack0.message.acked_type, ack0.message.acked_seq) == (MsgType.DISARM, 3)


# 5. `= hello`: the first example's exchange; the host's token seeded with 0
def test_the_hello_of_the_examples() -> None:
    assert random.Random(0).randrange(1 << 32) == 0xD82C07CD  # the host's token, seed 0
    emu = DeviceEmulator(nonce_seed=0)
    version, limits = _replies(emu, encode(Hello(3, 0xBEEF), seq=1))
    assert version.session == limits.session == 0xD82C07CE
    assert (version.seq, limits.seq) == (1, 2)


# 6. The reference point of "ahead by more than 1 % + 50 ms"
@pytest.mark.parametrize("t0_s", [0.0, 5.0, 86_400.0])
def test_device_time_is_measured_from_the_first_trusted_sample_and_the_arm(t0_s: float) -> None:
    c0 = 100.0  # the host's clock when the ARM's ACK arrived
    host_s = 2.0
    bound = (1.0 + CLOCK_RATE_TOLERANCE) * host_s + CLOCK_SLACK_S

    def sample(t: float, tick: int) -> TelemetrySample:
        return TelemetrySample(t, tick, 0.5, 0.25, 0.0, 4.0, 4.0, 1, 0, 0, 7)

    for ahead, ends in ((bound - 0.001, False), (bound + 0.001, True)):
        watch = TelemetryWatch(5.0, c0, table_crc32=7)
        first = sample(t0_s, 10)
        ticks = round(ahead * 10_000)
        later = sample(t0_s + ticks * 1e-4, 10 + ticks)
        found = watch.check([first, later], c0 + host_s, False)
        assert (found is not None and found.kind == "device_clock") is ends


# 7. The emulator takes SIM_OPERATOR silently; an unknown type is NAKed UNKNOWN_TYPE
def test_sim_operator_tells_the_emulator() -> None:
    emu = DeviceEmulator(nonce_seed=0)
    session = _hello(emu)
    assert _replies(emu, encode(SimOperator(0, 0.0), seq=2, session=session)) == []
    nan = _replies(emu, encode(SimOperator(1, float("nan")), seq=3, session=session))
    assert _nak(nan) == (MsgType.SIM_OPERATOR, 3, NakReason.NONFINITE)
