"""Fuzz the device emulator with sequences of well-framed host commands carrying hostile values.

Random uploads (valid and corrupt), ARM/DISARM/STOP/RESET, heartbeats, simulated hands pushing
up to +-100 N or with non-finite values, and control ticks, in any order, in a session opened
with HELLO (a SIM_RESET ends it: what follows is refused, as it must be). After every step the
device must hold its safety invariants: no exception, a finite force command within 0..78 N,
the drill never deeper than the uploaded stop depth, and only decodable frames on the wire.
"""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import event, example, given
from hypothesis import strategies as st

from tests.robustness.fuzz import FUZZ_TIMEOUT_S, fuzz_settings

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(FUZZ_TIMEOUT_S)]

hostile_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32),
    st.sampled_from([0.0, -0.0, -1.0, 1e-30, 3.4e38, math.nan, math.inf, -math.inf]),
)
u16 = st.integers(0, 0xFFFF)


@st.composite
def valid_upload(draw: st.DrawFn) -> list[object]:
    """PROFILE_BEGIN, its chunks and PROFILE_END with the right CRC (a table the device loads)."""
    from ctdrill.haptics import protocol as p

    n = draw(st.integers(1, 40))
    step = draw(st.floats(0.01, 1.0))
    rows = [
        (
            draw(st.floats(0.0, 30.0, width=32)),
            draw(st.floats(-10.0, 10.0, width=32)),
            draw(st.floats(-10.0, 10.0, width=32)),
        )
        for _ in range(n)
    ]
    begin = p.ProfileBegin(
        n,
        step,
        draw(st.floats(0.0, 2.0)),
        draw(st.floats(0.0, 500.0)),
        draw(st.floats(0.0, 500.0)),
        draw(st.floats(0.0, n * step * 1.5)),
    )
    # the device sees float32 values: compute the CRC on what goes over the wire
    wire = p.decode(p.encode(begin, seq=0)[:-1]).message
    assert isinstance(wire, p.ProfileBegin)
    begin = wire
    rows = [tuple(struct.unpack("<fff", struct.pack("<fff", *r))) for r in rows]
    chunks = [p.ProfileChunk(i, tuple(rows[i : i + 16])) for i in range(0, n, 16)]
    return [begin, *chunks, p.ProfileEnd(n, p.profile_crc32(begin, rows))]


@st.composite
def hostile_message(draw: st.DrawFn) -> object:
    """One host command with arbitrary field values (framing and CRC are right)."""
    from ctdrill.haptics import protocol as p

    kind = draw(st.sampled_from(["begin", "chunk", "end", "operator", "arm", "device-type"]))
    if kind == "begin":
        return p.ProfileBegin(draw(u16), *[draw(hostile_floats) for _ in range(5)])
    if kind == "chunk":
        rows = draw(st.lists(st.tuples(*[hostile_floats] * 3), min_size=1, max_size=16))
        return p.ProfileChunk(draw(u16), tuple(rows))
    if kind == "end":
        return p.ProfileEnd(draw(u16), draw(st.integers(0, 0xFFFFFFFF)))
    if kind == "operator":
        return p.SimOperator(draw(st.integers(0, 255)), draw(hostile_floats))
    if kind == "arm":  # an ARM naming some table, most likely not the loaded one
        return p.Arm(draw(st.integers(0, 0xFFFFFFFF)))
    return p.Ack(draw(st.integers(0, 255)), draw(u16))  # a device->host type sent to the device


#: The simulated hand: mostly pushing in (up to 100 N, beyond the 78 N device limit), sometimes
#: pulling back, or feeding at a set speed.
hands = st.one_of(
    st.builds(lambda f: _operator(1, f), st.floats(0.0, 100.0)),
    st.builds(lambda f: _operator(1, f), st.floats(-100.0, 0.0)),
    st.builds(lambda v: _operator(2, v), st.floats(-5.0, 20.0)),
)


def _operator(kind: int, value: float) -> object:
    from ctdrill.haptics.protocol import SimOperator

    return SimOperator(kind, value)


@st.composite
def actions(draw: st.DrawFn) -> list[tuple[str, object]]:
    from ctdrill.haptics import protocol as p

    simple = {
        "disarm": p.Disarm(),
        "stop": p.Stop(),
        "heartbeat": p.Heartbeat(),
        "reset": p.SimReset(),
    }
    upload = draw(valid_upload())
    crc = upload[-1].crc32  # ARM names the table uploaded last
    out: list[tuple[str, object]] = [("send", m) for m in upload]
    out += [("send", p.Arm(crc)), ("send", draw(hands)), ("tick", draw(st.integers(200, 1500)))]
    for _ in range(draw(st.integers(1, 12))):
        choice = draw(st.sampled_from(["tick", "tick", "upload", "hostile", "simple", "push"]))
        if choice == "tick":
            out.append(("tick", draw(st.integers(1, 1500))))
        elif choice == "upload":
            upload = draw(valid_upload())
            crc = upload[-1].crc32
            out += [("send", m) for m in upload]
        elif choice == "hostile":
            out.append(("send", draw(hostile_message())))
        elif choice == "push":
            out.append(("send", draw(hands)))
        else:
            name = draw(st.sampled_from([*sorted(simple), "arm"]))
            out.append(("send", p.Arm(crc) if name == "arm" else simple[name]))
    return out


def check_invariants(device: object, *, ticked: bool) -> None:
    """Force within -release bound..peak (negative only from the release damper, which brakes
    a master moving back by at most the continuous rating); front (and, after a tick, the
    drill) never past the stop depth.

    ``drill_mm`` is refreshed by the tick: right after a new table is loaded it still holds the
    previous session's value until the next tick (no telemetry is sent in between).
    """
    from ctdrill.haptics.emulator import DeviceEmulator
    from ctdrill.haptics.renderer import PEAK_FORCE_N, RELEASE_MAX_N

    assert isinstance(device, DeviceEmulator)
    r = device.renderer
    assert math.isfinite(r.force_cmd_n), r.force_cmd_n
    assert -RELEASE_MAX_N <= r.force_cmd_n <= PEAK_FORCE_N, r.force_cmd_n
    if r.has_profile:
        if ticked:
            assert r.drill_mm <= r.stop_depth_mm + 1e-9, (r.drill_mm, r.stop_depth_mm)
        assert r.front_mm <= r.stop_depth_mm + 1e-9, (r.front_mm, r.stop_depth_mm)


def _retraction_to_the_travel_end() -> list[tuple[str, object]]:
    """A hand pulling 46 N from ARM on: the handle jolts against the travel's end stop and
    bounces, and the release damper brakes it with the most pull it may leave (-20 N)."""
    from ctdrill.haptics import protocol as p

    begin = p.ProfileBegin(1, 1.0, 0.0, 0.0, 0.0, 0.0)
    rows = [(0.0, 0.0, 0.0)]
    crc = p.profile_crc32(begin, rows)
    upload = [begin, p.ProfileChunk(0, tuple(rows)), p.ProfileEnd(1, crc)]
    return [("send", m) for m in upload] + [
        ("send", p.Arm(crc)),
        ("send", _operator(1, -46.0)),
        ("tick", 200),
        ("tick", 1),
    ]


@fuzz_settings
@given(steps=actions())
@example(steps=_retraction_to_the_travel_end())
def test_fuzz_device_commands_keep_safety_invariants(steps: list[tuple[str, object]]) -> None:
    from ctdrill.haptics.emulator import DeviceEmulator
    from ctdrill.haptics.protocol import FrameReader, Heartbeat, MessageError, Packet
    from tests.haptics.wire import Wire

    device = DeviceEmulator(nonce_seed=0)
    wire = Wire(device)
    wire.hello()
    reader = FrameReader()
    deepest = 0.0
    for action, arg in steps:
        if action == "tick":
            assert isinstance(arg, int)
            done = 0
            while done < arg:  # the host's heartbeat every 20 ms keeps the watchdog fed
                n = min(200, arg - done)
                device.run_ticks(n)
                done += n
                check_invariants(device, ticked=True)
                device.receive(wire.frame(Heartbeat()))
        else:
            try:
                frame = wire.frame(arg)  # type: ignore[arg-type]
            except MessageError:
                continue  # the host cannot even encode it: nothing reaches the device
            device.receive(frame)
            check_invariants(device, ticked=False)
            if type(arg).__name__ == "SimReset":
                wire.hello()  # the power-cycle ended the session: open a new one
        for item in reader.feed(device.take_output()):
            assert isinstance(item, Packet), f"device sent an undecodable frame: {item}"
        deepest = max(deepest, device.renderer.drill_mm)
    event(f"drill reached {'> 0' if deepest > 0.0 else '0'} mm")
