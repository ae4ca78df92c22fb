"""Fuzz the serial decoder: mutated frames and garbage never escape as anything but ProtocolError,
never grow the reader's buffer, and never stop the next valid frame from being decoded."""

from __future__ import annotations

import contextlib

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.robustness.fuzz import FUZZ_TIMEOUT_S, byte_mutations, fuzz_settings
from tests.robustness.mutate import ByteMutation, apply_bytes

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(FUZZ_TIMEOUT_S)]


def valid_frames() -> list[bytes]:
    """One encoded frame of several message types (host and device side)."""
    from ctdrill.haptics import protocol as p

    messages: list[p.Message] = [
        p.Hello(),
        p.Heartbeat(),
        p.ProfileBegin(3, 0.05, 0.25, 30.0, 60.0, 4.5),
        p.ProfileChunk(0, ((1.0, 0.1, 0.05), (2.0, 0.2, 0.1), (3.0, 0.3, 0.15))),
        p.ProfileEnd(3, 0xDEADBEEF),
        p.Telemetry(7, 1.0, 0.9, 0.4, 3.2, 3.1, 2, 0, 0, 0xCAFE),
        p.Ack(0x10, 5),
        p.Nak(0x11, 6, 1),
    ]
    return [p.encode(m, seq=i, time_us=1000 * i) for i, m in enumerate(messages)]


FRAMES = valid_frames()
HEARTBEAT = FRAMES[1]


@fuzz_settings
@given(
    frame=st.sampled_from(FRAMES),
    mutations=byte_mutations(),
    garbage=st.binary(max_size=600),
    split=st.integers(1, 64),
)
def test_fuzz_frame_reader(
    frame: bytes, mutations: list[ByteMutation], garbage: bytes, split: int
) -> None:
    from ctdrill.haptics.protocol import MAX_DECODED, FrameReader, Packet, ProtocolError, decode

    data = frame
    for mutation in mutations:
        data = apply_bytes(data, mutation, [])
    # decode() of the raw frame (without its delimiter) only raises ProtocolError
    with contextlib.suppress(ProtocolError):
        decode(data.rstrip(b"\x00"))
    reader = FrameReader()
    stream = garbage + data + b"\x00" + HEARTBEAT
    out: list[Packet | ProtocolError] = []
    for start in range(0, len(stream), split):  # arbitrary chunking of the serial reads
        out += reader.feed(stream[start : start + split])
        assert len(reader._buf) <= MAX_DECODED + 2
    assert all(isinstance(item, Packet | ProtocolError) for item in out)
    assert out, "the trailing heartbeat must come out"
    last = out[-1]
    assert isinstance(last, Packet), last
    assert last.seq == 1 and type(last.message).__name__ == "Heartbeat"
