"""docs/protocol.md against the code: every byte example replayed, every code table compared.

Each ```device-example block runs on a fresh emulator (nonce seed 0, as the document says):
``> bytes`` is sent by the host, ``< bytes`` must be exactly what the device writes next
(everything it wrote, in order), ``= ticks N`` runs N control ticks, ``= hello`` is the HELLO
exchange of the first example, ``= device-seq N`` sets the device's frame counter to N (its
wrap, without sending 2^32 frames). ``xx*N`` is the byte xx repeated N times; ``#`` starts a
comment.

Each ```host-example block runs ctdrill's host (:class:`HostDevice` and
:class:`TelemetryWatch`) on scripted device bytes: ``= armed`` opens a session on the emulator
(seed 0, token seed 0), uploads the document's one-row table and arms it, then only the
block's bytes reach the host; ``= hello`` starts a HELLO whose answers are the block's bytes;
``< bytes`` is a frame the device sends, ``= clock T`` sets the host's clock to T s after ARM,
``! verdict`` is what the host concludes there: ``ok``, ``kind: message`` (why it ends the
session) or ``refused: message`` (a HELLO answered outside its bounds).
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pytest

from ctdrill.haptics import messages
from ctdrill.haptics.codes import Fault, MsgType, NakReason
from ctdrill.haptics.device import DeviceError
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.framing import cobs_decode, crc32c
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.limits import HOST_SILENCE_S, LIMITS_BOUNDS, TICK_RATE_HZ
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import HEADER, MAX_DECODED, PROTOCOL_VERSION, Telemetry, encode
from ctdrill.haptics.sim import SimLink
from ctdrill.haptics.watch import TelemetryWatch

DOC = (Path(__file__).resolve().parents[2] / "docs" / "protocol.md").read_text(encoding="utf-8")
BLOCKS = re.findall(r"```device-example\n(.*?)\n```", DOC, flags=re.S)
HOST_BLOCKS = re.findall(r"```host-example\n(.*?)\n```", DOC, flags=re.S)
#: The one-row table of the document's examples (section 2.1).
DOC_TABLE = ProfileTable(
    depth_step_mm=0.5,
    s0_n=[4.0],
    s1_n=[0.0],
    s2_n=[0.0],
    ke_per_mm_s=0.25,
    freqs_hz=np.array([30.0, 60.0]),
    stop_depth_mm=0.25,
)


def _bytes(text: str) -> bytes:
    out = bytearray()
    for token in text.split():
        byte, _, count = token.partition("*")
        out += bytes([int(byte, 16)]) * (int(count) if count else 1)
    return bytes(out)


def _lines(block: str) -> list[tuple[str, str]]:
    out = []
    for line in block.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            out.append((line[0], line[1:].strip()))
    return out


class ReplayDevice(Protocol):
    """What :func:`replay_block` drives: the Python emulator or the C core's."""

    def receive(self, data: bytes) -> None: ...
    def take_output(self) -> bytes: ...
    def run_ticks(self, n: int) -> Any: ...


def replay_block(
    block: str,
    emu: ReplayDevice,
    *,
    set_device_seq: Callable[[int], None],
    handle: Callable[[], None] = lambda: None,
) -> None:
    """Replay one example block of the document on ``emu``: each ``>`` line received, each
    ``<`` line expected byte for byte before the next action; ``= hello``, ``= device-seq N``
    and ``= ticks N`` as the document defines them. ``handle`` runs after every receive (a
    board's deferred frame handling)."""
    expected = b""

    def check() -> None:
        nonlocal expected
        assert emu.take_output().hex(" ") == expected.hex(" ")
        expected = b""

    for kind, arg in _lines(block):
        if kind == "<":
            expected += _bytes(arg)
            continue
        check()
        if kind == ">":
            emu.receive(_bytes(arg))
            handle()
        elif arg == "hello":
            emu.receive(HELLO)
            handle()
            emu.take_output()
        else:
            verb, n = arg.split()
            if verb == "device-seq":
                set_device_seq(int(n))
            else:
                assert verb == "ticks"
                emu.run_ticks(int(n))
    check()


HELLO = _bytes(next(arg for kind, arg in _lines(BLOCKS[0]) if kind == ">"))


def test_the_document_has_the_examples_it_promises() -> None:
    assert len(BLOCKS) >= 18 and len(HOST_BLOCKS) >= 8
    text = "\n".join(BLOCKS)
    for what in (
        "BAD_SESSION",
        "STALE_SEQUENCE",
        "BAD_LENGTH",
        "BAD_FRAME",
        "BAD_VERSION",
        "BAD_HEADER",
        "NOT_READY",
        "PROFILE_CRC",
        "= device-seq",
        "HELLO seq ffffffff",
    ):
        assert what in text, what
    hosts = "\n".join(HOST_BLOCKS)
    for what in (
        "undefined state",
        "undefined fault flag",
        "non-finite",
        "device_clock",
        "refused",
    ):
        assert what in hosts, what
    assert f"# ctdrill device protocol (version {PROTOCOL_VERSION})" in DOC


@pytest.mark.parametrize("block", BLOCKS, ids=[f"example{i}" for i in range(len(BLOCKS))])
def test_byte_example_replays_on_the_emulator(block: str) -> None:
    emu = DeviceEmulator(nonce_seed=0)

    def set_seq(n: int) -> None:
        emu._seq = n

    replay_block(block, emu, set_device_seq=set_seq)


class _ScriptedLink:
    """The host's link after the scripted point: reads what the block's device sends."""

    name = "doc"

    def __init__(self, clock_s: float, *, answers: bool = False) -> None:
        self.pending = b""
        self.written = b""
        self.now = clock_s
        self.answers = answers  # the device's bytes answer the host's first frame

    def write(self, data: bytes) -> None:
        self.written += data

    def read(self) -> bytes:
        if self.answers and not self.written:
            return b""
        data, self.pending = self.pending, b""
        return data

    def wait(self, duration_s: float) -> None:
        self.now += duration_s

    def clock_s(self) -> float:
        return self.now

    def close(self) -> None:
        pass


def _verdict(host: HostDevice, watch: TelemetryWatch, clock_s: float) -> str:
    samples = host.poll()
    found = watch.check(samples, clock_s, host.lost_session(), host.untrusted())
    return "ok" if found is None else f"{found.kind}: {found.message}"


def replay_host_block(block: str) -> list[tuple[str, str]]:
    """``(expected, actual)`` for every ``!`` line of a host-example block."""
    out = []
    host: HostDevice | None = None
    watch: TelemetryWatch | None = None
    link: _ScriptedLink | None = None
    start = 0.0
    for kind, arg in _lines(block):
        if kind == "<":
            assert link is not None
            link.pending += _bytes(arg)
        elif kind == "=" and arg == "armed":
            emu = DeviceEmulator(nonce_seed=0)
            host = HostDevice(SimLink(emu), token_seed=0)
            info = host.hello()
            host.upload_profile(DOC_TABLE)
            host.arm()
            start = host.clock_s()
            link = _ScriptedLink(start)
            host.transport = link
            watch = TelemetryWatch(
                DOC_TABLE.stop_depth_mm,
                start,
                watchdog_ms=info.limits.watchdog_ms,
                tick_rate_hz=info.version.tick_rate_hz,
                table_crc32=DOC_TABLE.crc32,
            )
        elif kind == "=" and arg == "hello":
            link = _ScriptedLink(0.0, answers=True)
            host = HostDevice(link, token_seed=0, timeout_s=0.01)
        elif kind == "=":
            verb, value = arg.split()
            assert verb == "clock" and link is not None
            link.now = start + float(value)
        else:
            assert kind == "!" and host is not None and link is not None
            if watch is None:  # the HELLO's answers
                try:
                    host.hello()
                    actual = "accepted"
                except DeviceError as exc:
                    actual = f"refused: {exc}"
            else:
                actual = _verdict(host, watch, link.now)
            out.append((arg, actual))
    return out


@pytest.mark.parametrize("block", HOST_BLOCKS, ids=[f"host{i}" for i in range(len(HOST_BLOCKS))])
def test_host_example_replays_on_the_host(block: str) -> None:
    verdicts = replay_host_block(block)
    assert verdicts
    for expected, actual in verdicts:
        assert actual == expected or (expected.endswith("...") and actual.startswith(expected[:-3]))


def test_the_documented_table_is_the_examples_table() -> None:
    assert f"CRC-32 {DOC_TABLE.crc32:08x}" in DOC


def test_worked_example() -> None:
    block = DOC.split("### Worked example", 1)[1].split("```")[1]
    raw = _bytes(block.split("raw", 1)[1].split("header")[0])
    crc_line = block.split("header", 1)[1].splitlines()[1]
    crc_bytes = _bytes(crc_line.split("CRC-32C")[0])
    value = int(re.search(r"CRC-32C 0x([0-9A-F]{8})", crc_line).group(1), 16)  # type: ignore[union-attr]
    wire = _bytes(block.split("wire", 1)[1])
    assert len(raw) == HEADER.size == 18
    assert crc32c(raw) == value and struct.pack("<I", value) == crc_bytes
    assert cobs_decode(wire[:-1]) == raw + crc_bytes and wire[-1] == 0
    assert f"{len(wire)} bytes on" in DOC.split("### Worked example", 1)[1]


def _table(after: str) -> list[list[str]]:
    """The rows of the first Markdown table after the line ``after``."""
    text = DOC.split(after, 1)[1]
    rows = []
    started = False
    for line in text.splitlines():
        if line.startswith("|"):
            started = True
            cells = [c.strip() for c in line.strip("|").split("|")]
            if not set(cells[0]) <= {"-"}:
                rows.append(cells)
        elif started:
            break
    return rows[1:]  # without the header row


def test_message_table_and_body_sizes_match_the_code() -> None:
    rows = _table("## 2. Messages")
    assert {int(r[0], 16): r[1] for r in rows} == {int(t): t.name for t in MsgType}
    sizes = dict(
        re.findall(r"([A-Z_]+) (\d+)", DOC.split("Body sizes (bytes):")[1].split("\n\n")[0])
    )
    for t in MsgType:
        if t == MsgType.PROFILE_CHUNK:
            continue
        size = messages.FIXED[t].FMT.size
        assert int(sizes.get(t.name, 0)) == size, t.name
    assert "PROFILE_CHUNK 3 + 12·count" in DOC
    assert f"at most **{MAX_DECODED} bytes**" in DOC


def test_nak_reasons_and_fault_flags_match_the_code() -> None:
    naks = _table("### NAK reasons")
    assert {int(r[0]): r[1] for r in naks} == {int(r): r.name for r in NakReason}
    flags = _table("STOP makes any state safe.")
    assert {int(r[0], 16): r[1] for r in flags} == {int(f): f.name for f in Fault}


def test_limits_bounds_match_the_code() -> None:
    rows = _table("### 2.5 What the host accepts")
    assert [r[0].strip("`") for r in rows] == [b.field for b in LIMITS_BOUNDS]
    for row, bound in zip(rows, LIMITS_BOUNDS, strict=True):
        lo, hi = (float(v) for v in row[1].split(" .. "))
        assert (lo, hi) == (bound.lo, bound.hi), bound.field
    assert f"{TICK_RATE_HZ[0]} .. {TICK_RATE_HZ[1]} Hz" in DOC
    assert f"at most {HOST_SILENCE_S * 1000:.0f} ms" in DOC


def test_header_and_telemetry_sizes() -> None:
    header = _table("### Header (18 bytes)")
    assert [r[1] for r in header] == ["version", "type", "seq", "session", "time_us"]
    assert [int(r[0]) for r in header] == [0, 1, 2, 6, 10]
    frame = encode(Telemetry(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0, 0), seq=1, session=1)
    assert f"1 kHz), {len(frame)} bytes on the wire" in DOC
