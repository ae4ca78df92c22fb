"""The C core fuzzed under AddressSanitizer and UndefinedBehaviorSanitizer (run by
tests/firmware/test_c_fuzz.py in a subprocess with the ASan runtime preloaded).

``python -m tests.firmware.fuzz_core EXAMPLES`` runs three Hypothesis properties on the
sanitized builds (``-fsanitize=address,undefined,float-cast-overflow``, no recovery: a finding
aborts the process):

* the frame decoder: arbitrary byte streams (noise, truncated and mutated frames, runs past the
  longest frame) in arbitrary pieces, with ticks between; the device answers only well-formed
  device frames, keeps a defined state, and raises no floating-point exception;
* the state machine, differentially: random host sessions (every message type, valid and
  refused: wrong sessions and sequence numbers, NaN and extreme values, uploads in and out of
  order, right and wrong CRCs, resets) with ticks between, on the sanitized double build and on
  the Python emulator: the same bytes out, byte for byte;
* the same sessions on the single-precision build: well-formed frames, defined states, no
  floating-point exception (its floats differ from Python's by design).
"""

from __future__ import annotations

import contextlib
import sys
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ctdrill.haptics.ccore import CDeviceEmulator, load_core
from ctdrill.haptics.codes import DEVICE_TYPES
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.protocol import (
    Arm,
    Disarm,
    FrameReader,
    Heartbeat,
    Hello,
    Message,
    Packet,
    ProfileBegin,
    ProfileChunk,
    ProfileEnd,
    SimOperator,
    SimReset,
    Stop,
    Version,
    encode,
    profile_crc32,
)

F32 = st.floats(width=32)  # any float32: NaN, inf, subnormals, extremes
SMALL = st.floats(-100.0, 100.0, width=32)


def _check_output(data: bytes, precision: str) -> None:
    for item in FrameReader().feed(data):
        assert isinstance(item, Packet), f"{precision}: the device sent a bad frame: {item}"
        assert int(item.message.TYPE) in DEVICE_TYPES
        state = getattr(item.message, "state", 0)
        assert 0 <= state <= 3


def _fe_clean(*precisions: str) -> None:
    for precision in precisions:  # each build keeps its own record of the flags raised
        raised = load_core(precision, sanitize=True).fw_host_fe_raised()  # type: ignore[arg-type]
        assert raised == 0, f"{precision}: floating-point exception flags 0x{raised:x} raised"


@st.composite
def streams(draw: Any) -> list[tuple[bytes, int]]:
    """Pieces of bytes, each followed by some ticks."""
    frame = st.builds(
        lambda m, s, q: encode(m, seq=q, session=s),
        st.sampled_from([Heartbeat(), Stop(), Disarm(), Hello(3, 1), Arm(5), SimReset()]),
        st.integers(0, 2**32 - 1),
        st.integers(0, 2**32 - 1),
    )

    def mutate(b: bytes, i: int, v: int) -> bytes:
        if not b:
            return b
        i %= len(b)
        return b[:i] + bytes([v]) + b[i + 1 :]

    piece = st.one_of(
        st.binary(max_size=300),
        frame,
        st.builds(mutate, frame, st.integers(0, 300), st.integers(0, 255)),
        st.builds(lambda f, n: f[:n], frame, st.integers(0, 30)),
        st.builds(lambda n: b"\x01" * n + b"\x00", st.integers(250, 600)),
    )
    return draw(st.lists(st.tuples(piece, st.integers(0, 30)), max_size=12))


class _Session:
    """Builds host frames addressed to the current session (as the devices announce it)."""

    def __init__(self) -> None:
        self.session = 0
        self.seq = 0
        self.begin: ProfileBegin | None = None
        self.rows: list[tuple[float, float, float]] = []
        self.crc = 0

    def heard(self, data: bytes) -> None:
        for item in FrameReader().feed(data):
            if isinstance(item, Packet) and isinstance(item.message, Version):
                self.session = item.session

    def frame(self, draw: Any, msg: Message) -> bytes:
        mode = draw(st.sampled_from(["next", "next", "next", "same", "other", "zero"]))
        session = {"other": self.session ^ 0x55, "zero": 0}.get(mode, self.session)
        if mode != "same":
            self.seq += 1
        if isinstance(msg, Hello):
            self.seq = draw(st.sampled_from([1, 0xFFFFFFFF, 7]))
        try:
            return encode(msg, seq=self.seq & 0xFFFFFFFF, session=session)
        except Exception:  # a field out of its type's range: sent as garbage instead
            return b"\x02\x07\x00"

    def message(self, draw: Any) -> Message:
        kind = draw(
            st.sampled_from(
                ["hello", "begin", "chunk", "end", "arm", "disarm", "beat", "stop", "op", "reset"]
            )
        )
        if kind == "hello":
            return Hello(draw(st.sampled_from([3, 3, 3, 2])), draw(st.integers(0, 2**32 - 1)))
        if kind == "begin":
            n = draw(st.sampled_from([1, 2, 17, 0, 4096, 4097, 65535]))
            vals = [draw(st.one_of(st.floats(0.0625, 1.0, width=32), F32)) for _ in range(5)]
            self.begin = ProfileBegin(n, *vals)
            self.rows = []
            return self.begin
        if kind == "chunk":
            count = draw(st.integers(1, 16))
            rows = [tuple(draw(st.one_of(SMALL, F32)) for _ in range(3)) for _ in range(count)]
            first = len(self.rows) if draw(st.booleans()) else draw(st.integers(0, 40))
            if first == len(self.rows):
                self.rows += rows
            return ProfileChunk(first, tuple(rows))  # type: ignore[arg-type]
        if kind == "end":
            n = self.begin.n_steps if self.begin else draw(st.integers(0, 20))
            crc = draw(st.integers(0, 2**32 - 1))
            if self.begin is not None and draw(st.booleans()):
                with contextlib.suppress(Exception):  # a row out of float32's range
                    crc = profile_crc32(self.begin, self.rows)
            self.crc = crc
            return ProfileEnd(n, crc)
        if kind == "arm":
            return Arm(self.crc if draw(st.booleans()) else draw(st.integers(0, 2**32 - 1)))
        if kind == "op":
            return SimOperator(draw(st.integers(0, 3)), draw(st.one_of(SMALL, F32)))
        return {"disarm": Disarm(), "beat": Heartbeat(), "stop": Stop(), "reset": SimReset()}[kind]


def run(examples: int) -> None:
    common = settings(
        max_examples=examples,
        deadline=None,
        derandomize=examples <= 200,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )

    @common
    @given(streams(), st.sampled_from(["double", "single"]))
    def frame_decoder(stream: list[tuple[bytes, int]], precision: str) -> None:
        dev = CDeviceEmulator(nonce_seed=1, precision=precision, sanitize=True)  # type: ignore[arg-type]
        for data, ticks in stream:
            dev.receive(data)
            dev.run_ticks(ticks)
        _check_output(dev.take_output(), precision)
        assert 0 <= dev.state <= 3
        _fe_clean(precision)

    @common
    @given(st.data())
    def state_machine(data: Any) -> None:
        c = CDeviceEmulator(nonce_seed=2, precision="double", sanitize=True)
        s = CDeviceEmulator(nonce_seed=2, precision="single", sanitize=True)
        py = DeviceEmulator(nonce_seed=2)
        host = _Session()
        out_c, out_py = bytearray(), bytearray()
        for _ in range(data.draw(st.integers(1, 30))):
            frame = host.frame(data.draw, host.message(data.draw))
            for dev in (c, s, py):
                dev.receive(frame)
            ticks = data.draw(st.sampled_from([0, 0, 1, 10, 37, 200, 600]))
            for dev in (c, s, py):
                dev.run_ticks(ticks)
            got_c, got_py = c.take_output(), py.take_output()
            _check_output(s.take_output(), "single")
            host.heard(got_py)
            out_c += got_c
            out_py += got_py
            assert bytes(out_c) == bytes(out_py), "the C core and the Python device differ"
        _check_output(bytes(out_c), "double")
        _fe_clean("double", "single")

    frame_decoder()
    state_machine()


if __name__ == "__main__":
    run(int(sys.argv[1]) if len(sys.argv) > 1 else 50)
    print("fuzzed: no finding")
