"""docs/protocol.md against the code: every byte example replayed, every code table compared.

Each ```device-example block runs on a fresh emulator (nonce seed 0, as the document says):
``> bytes`` is sent by the host, ``< bytes`` must be exactly what the device writes next
(everything it wrote, in order), ``= ticks N`` runs N control ticks, ``= hello`` is the HELLO
exchange of the first example. ``xx*N`` is the byte xx repeated N times; ``#`` starts a comment.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path

import pytest

from ctdrill.haptics import messages
from ctdrill.haptics.codes import Fault, MsgType, NakReason
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.framing import cobs_decode, crc16_ccitt_false
from ctdrill.haptics.protocol import HEADER, MAX_DECODED, Telemetry, encode

DOC = (Path(__file__).resolve().parents[2] / "docs" / "protocol.md").read_text(encoding="utf-8")
BLOCKS = re.findall(r"```device-example\n(.*?)\n```", DOC, flags=re.S)


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


HELLO = _bytes(next(arg for kind, arg in _lines(BLOCKS[0]) if kind == ">"))


def test_the_document_has_the_examples_it_promises() -> None:
    assert len(BLOCKS) >= 13
    text = "\n".join(BLOCKS)
    for what in ("BAD_SESSION", "STALE_SEQUENCE", "BAD_LENGTH", "BAD_FRAME", "BAD_VERSION"):
        assert what in text, what


@pytest.mark.parametrize("block", BLOCKS, ids=[f"example{i}" for i in range(len(BLOCKS))])
def test_byte_example_replays_on_the_emulator(block: str) -> None:
    emu = DeviceEmulator(nonce_seed=0)
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
        elif arg == "hello":
            emu.receive(HELLO)
            emu.take_output()
        else:
            verb, n = arg.split()
            assert verb == "ticks"
            emu.run_ticks(int(n))
    check()


def test_worked_example() -> None:
    block = DOC.split("### Worked example", 1)[1].split("```")[1]
    raw = _bytes(block.split("raw", 1)[1].split("header")[0])
    crc_line = block.split("header", 1)[1].splitlines()[1]
    crc_bytes = _bytes(crc_line.split("CRC-16")[0])
    value = int(re.search(r"CRC-16 0x([0-9A-F]{4})", crc_line).group(1), 16)  # type: ignore[union-attr]
    wire = _bytes(block.split("wire", 1)[1])
    assert len(raw) == HEADER.size == 18
    assert crc16_ccitt_false(raw) == value and struct.pack("<H", value) == crc_bytes
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


def test_header_and_telemetry_sizes() -> None:
    header = _table("### Header (18 bytes)")
    assert [r[1] for r in header] == ["version", "type", "seq", "session", "time_us"]
    assert [int(r[0]) for r in header] == [0, 1, 2, 6, 10]
    frame = encode(Telemetry(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0), seq=1, session=1)
    assert f"1 kHz), {len(frame)} bytes on the wire" in DOC
