"""The host's watch of the telemetry: each reason to end a session, at its boundary, and each
class of report the host cannot trust (issue 29: the host decides from its own clock and its
own bounds)."""

from __future__ import annotations

import itertools
import math
import struct
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.haptics.codes import KNOWN_FAULT_BITS, KNOWN_STATES
from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.limits import HOST_SILENCE_S, silence_bound_s
from ctdrill.haptics.protocol import DeviceState, Fault
from ctdrill.haptics.watch import TelemetryWatch, stop_tolerance_mm

TABLE = 0x1234ABCD


def _sample(
    drill_mm: float, state: int = DeviceState.STOPPED, faults: int = 0, *, tick: int = 10
) -> TelemetrySample:
    """A sample at ``tick`` (10 kHz: 100 us per tick) naming the table :data:`TABLE`."""
    return TelemetrySample(
        tick * 1e-4, tick, drill_mm + 1.0, drill_mm, 0.0, 10.0, 10.0, state, faults, 0, TABLE
    )


def _watch(**kwargs: int) -> TelemetryWatch:
    return TelemetryWatch(5.0, 0.0, table_crc32=TABLE, **kwargs)


def _stream(n: int, start_tick: int = 10) -> list[TelemetrySample]:
    return [_sample(1.0, DeviceState.CUTTING, tick=start_tick + 10 * i) for i in range(n)]


def test_stop_tolerance_is_one_encoder_count_plus_float32_rounding() -> None:
    stop = 10.8
    assert stop_tolerance_mm(stop) == pytest.approx(1e-4 + 10.8 * 2.0**-22)
    wire = struct.unpack("<f", struct.pack("<f", stop))[0]  # the stop depth the device holds
    assert wire - stop < stop_tolerance_mm(stop) - 1e-4
    watch = TelemetryWatch(stop, 0.0)
    assert watch.check([_sample(wire + 1e-4)], 0.0, False) is None  # the device's stop + 1 count
    found = watch.check([_sample(stop + 2.1e-4, tick=20)], 0.0, False)
    assert found is not None and found.kind == "drill_past_stop"
    assert found.recorded == 1  # a well-formed report of a drill past the stop is recorded


@pytest.mark.parametrize(
    ("state", "faults", "ends"),
    [
        (DeviceState.CUTTING, 0, False),
        (DeviceState.STOPPED, Fault.PEAK_LIMIT | Fault.THERMAL_LIMIT | Fault.TRAVEL_LIMIT, False),
        (DeviceState.CUTTING, Fault.WATCHDOG, True),
        (DeviceState.CUTTING, Fault.RESET, True),
        (DeviceState.SAFE, Fault.HOST_STOP, True),
        (DeviceState.IDLE, 0, True),
    ],
)
def test_device_faults_and_states(state: int, faults: int, ends: bool) -> None:
    found = _watch().check([_sample(1.0, state, faults)], 0.0, False)
    assert (found is not None) == ends
    if found is not None:
        assert found.kind == "device_fault" and found.recorded == 1


@pytest.mark.parametrize(
    "field", ["master_mm", "drill_mm", "velocity_mm_s", "force_cmd_n", "force_est_n"]
)
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_number_ends_the_session_unrecorded(field: str, bad: float) -> None:
    samples = _stream(3)
    samples[2] = replace(samples[2], **{field: bad})
    found = _watch().check(samples, 0.01, False)
    assert found is not None and found.kind == "device_fault" and field in found.message
    assert found.recorded == 2  # the two before it; never the NaN itself


@pytest.mark.parametrize("state", [4, 5, 17, 255])
def test_an_undefined_state_ends_the_session(state: int) -> None:
    assert state not in KNOWN_STATES
    found = _watch().check([_sample(1.0, state)], 0.0, False)
    assert found is not None and found.kind == "device_fault"
    assert f"undefined state {state}" in found.message and found.recorded == 0


@pytest.mark.parametrize("bit", [1 << k for k in range(8, 16)])
def test_an_undefined_fault_flag_ends_the_session(bit: int) -> None:
    assert not bit & KNOWN_FAULT_BITS
    found = _watch().check([_sample(1.0, DeviceState.CUTTING, bit | Fault.PEAK_LIMIT)], 0.0, False)
    assert found is not None and found.kind == "device_fault"
    assert f"0x{bit:04x}" in found.message and found.recorded == 0


def test_another_table_ends_the_session() -> None:
    found = _watch().check([replace(_sample(1.0), table_crc32=TABLE ^ 1)], 0.0, False)
    assert found is not None and found.kind == "device_fault" and "table" in found.message


@pytest.mark.parametrize(
    ("case", "time_s", "tick"),
    [
        ("backwards", 0.0005, 30),  # time runs back, ticks forward
        ("frozen", 0.002, 20),  # the same time and tick again
        ("frozen time", 0.002, 30),  # ticks advance, time does not
        ("jump near 2^64", (2**64 - 1) * 1e-6, 30),
        ("jump by a second", 1.003, 30),
        ("ticks without time", 0.003, 1030),
    ],
)
def test_device_time_that_does_not_advance_with_its_ticks_ends_the_session(
    case: str, time_s: float, tick: int
) -> None:
    first, second = _stream(2)
    bad = replace(second, time_s=time_s, tick=tick)
    found = _watch().check([first, second, bad], 10.0, False)
    assert found is not None and found.kind == "device_clock", case
    assert found.recorded == 2


def test_device_time_running_ahead_of_the_host_clock_ends_the_session() -> None:
    # 1 s of device time (consistent ticks) while the host's clock moved 0.5 s
    samples = _stream(1001)
    watch = _watch()
    assert watch.check(samples[:500], 0.5, False) is None
    found = watch.check(samples[500:], 0.5, False)
    assert found is not None and found.kind == "device_clock" and "ahead" in found.message
    # within 1 % plus 50 ms it is a clock, not a lie
    assert _watch().check(samples[:551], 0.5, False) is None


def test_lost_frames_and_the_tick_counter_wrap_are_fine() -> None:
    samples = _stream(3, start_tick=2**32 - 15)  # ticks wrap past 2^32 (5 days at 10 kHz)
    samples = [replace(s, tick=s.tick & 0xFFFFFFFF) for s in samples]
    samples.append(
        replace(
            samples[-1], time_s=samples[-1].time_s + 3e-3, tick=(samples[-1].tick + 30) & 0xFFFFFFFF
        )
    )
    assert _watch().check(samples, 1.0, False) is None  # a gap of 3 ms: two frames lost


def test_silence_is_bounded_by_the_hosts_own_clock() -> None:
    assert silence_bound_s(50) == pytest.approx(0.1)
    assert silence_bound_s(20) == pytest.approx(0.04)
    assert silence_bound_s(65535) == HOST_SILENCE_S  # whatever the device announces
    watch = _watch(watchdog_ms=65535)
    assert watch.check([], 0.1, False) is None
    found = watch.check([], 0.1001, False)
    assert found is not None and found.kind == "telemetry_silent"
    assert watch.check(_stream(1), 2.0, False) is None  # heard again: the silence restarts
    found = watch.check([], 2.0, True)
    assert found is not None and found.kind == "device_reset"


def test_an_untrusted_fault_report_ends_the_session() -> None:
    found = _watch().check(_stream(2), 0.01, False, "a FAULT report with an undefined flag")
    assert found is not None and found.kind == "device_fault" and found.recorded == 2


def test_last_words_are_trusted_up_to_the_first_bad_one() -> None:
    samples = _stream(4)
    samples[2] = replace(samples[2], force_cmd_n=math.inf)
    assert _watch().trusted(samples, 1.0) == samples[:2]


@settings(max_examples=60)
@given(
    st.lists(
        st.tuples(
            st.floats(allow_nan=True, allow_infinity=True),
            st.integers(0, 2**32 - 1),
            st.floats(allow_nan=True, allow_infinity=True),
            st.integers(0, 255),
            st.integers(0, 0xFFFF),
        ),
        max_size=8,
    )
)
def test_nothing_untrusted_is_ever_recorded(rows: list[tuple[float, int, float, int, int]]) -> None:
    # Whatever a device sends, the watch answers (no exception) and the samples it lets the
    # session record are finite, of defined states and flags, in increasing device time.
    samples = [
        TelemetrySample(
            abs(t) % 1e6 if math.isfinite(t) else t,
            tick,
            x,
            0.0,
            0.0,
            1.0,
            1.0,
            state,
            faults,
            0,
            TABLE,
        )
        for t, tick, x, state, faults in rows
    ]
    found = _watch().check(samples, 1e9, False)
    kept = samples if found is None else samples[: found.recorded]
    for a in kept:
        assert math.isfinite(a.master_mm) and a.state in KNOWN_STATES
        assert not a.faults & ~KNOWN_FAULT_BITS
    assert all(b.time_s > a.time_s for a, b in itertools.pairwise(kept))
