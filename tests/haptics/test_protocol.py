"""Framing against hand-checked byte tables, round trips, and fuzzing (only typed errors escape)."""

from __future__ import annotations

import contextlib
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ctdrill.haptics.protocol import (
    MAX_CHUNK_ROWS,
    Ack,
    Arm,
    ChecksumError,
    FaultReport,
    FrameReader,
    FramingError,
    Heartbeat,
    Hello,
    Limits,
    MessageError,
    Nak,
    Packet,
    ProfileBegin,
    ProfileChunk,
    ProfileEnd,
    ProtocolError,
    SimOperator,
    Telemetry,
    Version,
    cobs_decode,
    cobs_encode,
    crc32,
    crc32c,
    decode,
    encode,
    profile_crc32,
    seq_after,
)


def _crc32c_bitwise(data: bytes) -> int:
    """Independent bit-by-bit CRC-32C (no table) to check the table version."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x82F63B78 if crc & 1 else crc >> 1
    return crc ^ 0xFFFFFFFF


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def test_check_values() -> None:
    assert crc32c(b"123456789") == 0xE3069283  # the CRC catalogue's CRC-32/ISCSI check
    assert _crc32c_bitwise(b"123456789") == 0xE3069283
    assert crc32(b"123456789") == 0xCBF43926


# COBS examples of the original paper (Cheshire & Baker) / Wikipedia table.
COBS_TABLE = [
    ("00", "01 01"),
    ("00 00", "01 01 01"),
    ("11 22 00 33", "03 11 22 02 33"),
    ("11 22 33 44", "05 11 22 33 44"),
    ("11 00 00 00", "02 11 01 01 01"),
]


@pytest.mark.parametrize(("raw", "enc"), COBS_TABLE)
def test_cobs_table(raw: str, enc: str) -> None:
    assert cobs_encode(h(raw)) == h(enc)
    assert cobs_decode(h(enc)) == h(raw)


def test_cobs_254_run() -> None:
    data = bytes(range(1, 255))  # 254 non-zero bytes: one 0xFF block, then an empty last block
    assert cobs_encode(data) == b"\xff" + data + b"\x01"
    assert cobs_decode(cobs_encode(data)) == data


# Frames: header (version 03, type, seq u32 LE, session u32 LE, time_us u64 LE) + body +
# CRC-32C LE, COBS, 00. Session 0x1A2B3C4D = 4d 3c 2b 1a. "raw" is spelled field by field; its
# last four bytes are checked against the bit-by-bit CRC, the wire against the raw by COBS.
FRAME_TABLE = [
    # HEARTBEAT seq 5: 03 22 | 05 00 00 00 | 4d 3c 2b 1a | 8x 00 | crc 0xACD2A625
    (
        Heartbeat(),
        5,
        0x1A2B3C4D,
        0,
        "03 22 05000000 4d3c2b1a 0000000000000000 25a6d2ac",
        "04 03 22 05 01 01 05 4d 3c 2b 1a 01 01 01 01 01 01 01 05 25 a6 d2 ac 00",
    ),
    # HELLO seq 1, no session yet; body: version 03, host token 0xCAFEF00D
    (
        Hello(3, 0xCAFEF00D),
        1,
        0,
        0,
        "03 01 01000000 00000000 0000000000000000 03 0df0feca a1b1f255",
        "04 03 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 0a 03 0d f0 fe ca a1 b1 f2 55 00",
    ),
    # ACK of (HEARTBEAT, seq 5), device seq 7, t = 1000 us = e8 03
    (
        Ack(0x22, 5),
        7,
        0x1A2B3C4D,
        1000,
        "03 40 07000000 4d3c2b1a e803000000000000 22 05000000 0b7d33af",
        "04 03 40 07 01 01 07 4d 3c 2b 1a e8 03 01 01 01 01 01 03 22 05 01 01 05 0b 7d 33 af 00",
    ),
    # NAK (ARM, seq 9, NOT_READY=5), device seq 2, t = 16 us
    (
        Nak(0x20, 9, 5),
        2,
        0x1A2B3C4D,
        16,
        "03 41 02000000 4d3c2b1a 1000000000000000 20 09000000 05 29a84487",
        "04 03 41 02 01 01 06 4d 3c 2b 1a 10 01 01 01 01 01 01 03 20 09 01 01 06 05 29 a8 44 87 00",
    ),
    # ARM seq 4 of the table whose CRC-32 is 0xDEADBEEF (ef be ad de)
    (
        Arm(0xDEADBEEF),
        4,
        0x1A2B3C4D,
        0,
        "03 20 04000000 4d3c2b1a 0000000000000000 efbeadde d0286555",
        "04 03 20 04 01 01 05 4d 3c 2b 1a 01 01 01 01 01 01 01 09 ef be ad de d0 28 65 55 00",
    ),
    # TELEMETRY seq 0x1234, t = 0x0102030405 us; tick 10, master 1.5 (00 00 c0 3f),
    # drill 1.0 (00 00 80 3f), velocity -2.0 (00 00 00 c0), force_cmd 3.25 (00 00 50 40),
    # force_est 0.0, state 1 (cutting), faults 0, overruns 0, table CRC-32 0xDEADBEEF
    (
        Telemetry(10, 1.5, 1.0, -2.0, 3.25, 0.0, 1, 0, 0, 0xDEADBEEF),
        0x1234,
        0x1A2B3C4D,
        0x0102030405,
        "03 30 34120000 4d3c2b1a 0504030201000000 0a000000 0000c03f 0000803f 000000c0"
        " 00005040 00000000 01 0000 0000 efbeadde 21d27790",
        "05 03 30 34 12 01 0a 4d 3c 2b 1a 05 04 03 02 01 01 01 02 0a 01 01 01 01 03 c0 3f 01 03"
        " 80 3f 01 01 02 c0 01 03 50 40 01 01 01 02 01 01 01 01 09 ef be ad de 21 d2 77 90 00",
    ),
    # PROFILE_CHUNK seq 3, first 0, 1 row (1.0, 0.5, 0.25) = 00 00 80 3f, 00 00 00 3f, 00 00 80 3e
    (
        ProfileChunk(0, ((1.0, 0.5, 0.25),)),
        3,
        0x1A2B3C4D,
        0,
        "03 11 03000000 4d3c2b1a 0000000000000000 0000 01 0000803f 0000003f 0000803e 9ab2577e",
        "04 03 11 03 01 01 05 4d 3c 2b 1a 01 01 01 01 01 01 01 01 01 02 01 01 03 80 3f 01 01 02"
        " 3f 01 07 80 3e 9a b2 57 7e 00",
    ),
]


@pytest.mark.parametrize(("message", "seq", "session", "time_us", "raw", "wire"), FRAME_TABLE)
def test_frame_table(
    message: object, seq: int, session: int, time_us: int, raw: str, wire: str
) -> None:
    frame, plain = h(wire), h(raw)
    assert plain[-4:] == struct.pack("<I", _crc32c_bitwise(plain[:-4]))
    assert cobs_decode(frame[:-1]) == plain
    assert encode(message, seq=seq, session=session, time_us=time_us) == frame  # type: ignore[arg-type]
    packet = decode(frame[:-1])
    assert packet == Packet(seq=seq, session=session, time_us=time_us, message=message)  # type: ignore[arg-type]


ALL_MESSAGES = [
    Hello(),
    Version(3, 0, 1, 0, 10000, 0xFFFFFFFF),
    Limits(78.0, 20.0, 5684.0, 50, 4096, -20.0, 60.0),
    ProfileBegin(800, 0.0625, 0.25, 30.0, 60.0, 12.5),  # float32-exact values
    ProfileChunk(16, tuple((float(i), 0.5, 0.25) for i in range(MAX_CHUNK_ROWS))),
    ProfileEnd(800, 0xDEADBEEF),
    Arm(0xFFFFFFFF),
    Heartbeat(),
    SimOperator(1, 10.0),
    Telemetry(2**32 - 1, 1.5, 1.0, -2.0, 3.25, 0.0, 3, 0xFFFF, 7, 0x12345678),
    FaultReport(1, 3),
]


@pytest.mark.parametrize("message", ALL_MESSAGES)
def test_round_trip(message: object) -> None:
    frame = encode(message, seq=70000, session=0xFFFFFFFF, time_us=2**40)  # type: ignore[arg-type]
    assert frame.count(0) == 1 and frame[-1] == 0
    packet = decode(frame[:-1])
    assert packet == Packet(seq=70000, session=0xFFFFFFFF, time_us=2**40, message=message)  # type: ignore[arg-type]


def test_profile_crc32_covers_header_and_rows() -> None:
    begin = ProfileBegin(2, 0.05, 0.25, 30.0, 60.0, 12.5)
    rows = [(1.0, 0.5, 0.25), (2.0, 0.0, 0.0)]
    body = struct.pack("<Hfffff", 2, 0.05, 0.25, 30.0, 60.0, 12.5)
    expected = crc32(body + struct.pack("<ffffff", 1.0, 0.5, 0.25, 2.0, 0.0, 0.0))
    assert profile_crc32(begin, rows) == expected
    assert profile_crc32(ProfileBegin(2, 0.05, 0.25, 30.0, 60.0, 12.0), rows) != expected


def test_typed_errors() -> None:
    good = encode(Heartbeat(), seq=1)[:-1]
    bad_crc = bytearray(cobs_decode(good))
    bad_crc[-1] ^= 0x01
    with pytest.raises(ChecksumError):
        decode(cobs_encode(bytes(bad_crc)))
    with pytest.raises(FramingError):
        decode(b"\x05\x01")  # block runs past the end
    with pytest.raises(FramingError):
        decode(b"")
    raw = bytearray(cobs_decode(good))
    raw[1] = 0x7F  # unknown type, valid CRC
    raw[-4:] = struct.pack("<I", crc32c(bytes(raw[:-4])))
    with pytest.raises(MessageError, match="unknown message type 0x7f"):
        decode(cobs_encode(bytes(raw)))
    with pytest.raises(MessageError) as unknown:
        decode(cobs_encode(bytes(raw)))
    assert unknown.value.header == (0x7F, 1, 0)  # the header was readable: a NAK can echo it
    raw[0] = 1  # version 1
    raw[-4:] = struct.pack("<I", crc32c(bytes(raw[:-4])))
    with pytest.raises(MessageError, match="version 1"):
        decode(cobs_encode(bytes(raw)))
    with pytest.raises(MessageError):
        encode(ProfileChunk(0, ()), seq=0)
    with pytest.raises(MessageError):
        encode(Ack(300, 0), seq=0)
    with pytest.raises(MessageError):
        encode(Heartbeat(), seq=2**32)
    assert issubclass(ProtocolError, ValueError)


def test_reader_splits_a_stream_and_survives_garbage() -> None:
    stream = encode(Hello(), seq=1) + b"\x13\x37" * 300 + b"\x00" + encode(Heartbeat(), seq=2)
    reader = FrameReader()
    items = []
    for i in range(0, len(stream), 7):  # arbitrary chunking
        items += reader.feed(stream[i : i + 7])
    packets = [x for x in items if isinstance(x, Packet)]
    errors = [x for x in items if isinstance(x, ProtocolError)]
    assert [p.message for p in packets] == [Hello(), Heartbeat()]
    assert len(errors) == 1 and isinstance(errors[0], FramingError)


@given(st.binary(max_size=600))
def test_fuzz_random_bytes(data: bytes) -> None:
    reader = FrameReader()
    for item in reader.feed(data):
        assert isinstance(item, Packet | ProtocolError)
    with contextlib.suppress(ProtocolError):
        decode(data)


@given(
    st.sampled_from(ALL_MESSAGES),
    st.lists(st.tuples(st.integers(0, 300), st.integers(0, 255)), min_size=1, max_size=6),
)
def test_fuzz_mutated_valid_frames(message: object, edits: list[tuple[int, int]]) -> None:
    frame = bytearray(encode(message, seq=9)[:-1])  # type: ignore[arg-type]
    for pos, value in edits:
        if pos < len(frame):
            frame[pos] = value
        else:
            frame.append(value)
    reader = FrameReader()
    for item in reader.feed(bytes(frame) + b"\x00" + encode(Heartbeat(), seq=10)):
        assert isinstance(item, Packet | ProtocolError)
    # Whatever came before, the reader resynchronises on the next delimiter.
    last = reader.feed(b"")
    assert last == []
    tail = FrameReader().feed(bytes(frame) + b"\x00" + encode(Heartbeat(), seq=10))
    assert isinstance(tail[-1], Packet) and tail[-1].message == Heartbeat()


def test_serial_number_arithmetic() -> None:
    # RFC 1982 on 32 bits: after = ahead by 1 .. 2^31 - 1; 0 comes after 0xFFFFFFFF
    assert seq_after(1, 0) and seq_after(0, 0xFFFFFFFF) and seq_after(5, 0xFFFFFFFE)
    assert not seq_after(7, 7) and not seq_after(6, 7) and not seq_after(0xFFFFFFFF, 0)
    assert seq_after(0x7FFFFFFF, 0) and not seq_after(0x80000000, 0)


def _syndromes(n_bytes: int, *, reflected: bool, poly: int, width: int) -> list[int]:
    """The check's change for every single flipped bit of an ``n_bytes`` frame (data and check
    field), from the polynomial: a CRC is affine, so an error pattern goes undetected exactly
    when the XOR of its bits' syndromes is 0. A data bit's error enters the register where the
    bit-serial algorithm feeds it and is shifted through every later bit."""
    top = 1 << (width - 1)
    mask = (1 << width) - 1

    def step(d: int) -> int:
        if reflected:
            return (d >> 1) ^ (poly if d & 1 else 0)
        return ((d << 1) & mask) ^ (poly if d & top else 0)

    out = []
    d = 1 if reflected else top
    for _ in range(n_bytes * 8):
        d = step(d)
        out.append(d)
    return out + [1 << k for k in range(width)]  # flipped bits of the check field itself


def _undetected_up_to_4_bits(syndromes: list[int]) -> bool:
    """Some pattern of 1 to 4 flipped bits leaves the check unchanged."""
    import numpy as np

    s = np.sort(np.asarray(syndromes, dtype=np.uint64))
    if s[0] == 0 or np.any(s[1:] == s[:-1]):
        return True  # weight 1 or 2
    i, j = np.triu_indices(len(s), k=1)
    pairs = np.sort(s[i] ^ s[j])
    # weight 3: a pair equal to a third bit; weight 4: two disjoint pairs equal (pairs sharing
    # a bit would mean two equal single syndromes, excluded above)
    at = np.minimum(np.searchsorted(s, pairs), len(s) - 1)
    return bool(np.any(s[at] == pairs) or np.any(pairs[1:] == pairs[:-1]))


def test_the_frame_check_detects_every_error_of_up_to_4_bits() -> None:
    # Hamming distance >= 5 for every frame length the protocol allows (the longest valid
    # frame, a 16-row PROFILE_CHUNK, is 213 bytes before its check; a shorter frame is a longer
    # one with leading zeros, its distance at least as large): CRC-32C has no undetected error
    # of 1-4 bits there (and, as any 32-bit CRC, catches every burst of up to 32 bits).
    # CRC-16/CCITT-FALSE, version 2's check, misses 4-bit errors already in a 22-byte HEARTBEAT.
    assert not _undetected_up_to_4_bits(_syndromes(213, reflected=True, poly=0x82F63B78, width=32))
    assert _undetected_up_to_4_bits(_syndromes(18, reflected=False, poly=0x1021, width=16))
