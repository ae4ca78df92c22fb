"""The host bounds what it hears (issue 36): every value a device reports is held to the LIMITS
it announced and to the physics of the master (finite, within the travel, the rendered force
within ``-continuous .. peak``, a reading of the hand and a speed no hand makes); outside, the
host sends STOP and DISARM and records a ``device_fault`` (exit 3), as for a NaN, and nothing
of the report reaches the records."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from ctdrill.haptics.device import DeviceInfo, DeviceRefused, TelemetrySample
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.limits import (
    END_STOP_READING_MULTIPLE,
    HAND_READING_PEAKS,
    MAX_SPEED_MM_S,
    telemetry_problem,
)
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState, Fault, Limits, Version
from ctdrill.haptics.retract import arm_retracted
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import parse_operator
from ctdrill.haptics.sim import SimLink, SimulatedDevice
from ctdrill.haptics.watch import TelemetryWatch
from tests.haptics.emulator_process import demo_rehearsal
from tests.haptics.hostile import HostileEmulator

#: Another device than the emulated master: 50 N peak, 12 N continuous, travel -8..35 mm.
OTHER = Limits(50.0, 12.0, 2000.0, 40, 2048, -8.0, 35.0)
TABLE = 0x0BADF00D


def _sample(**changes: float | int) -> TelemetrySample:
    base = TelemetrySample(0.001, 10, 4.0, 3.5, 12.0, 9.0, 9.5, DeviceState.CUTTING, 0, 0, TABLE)
    return replace(base, **changes)


@pytest.mark.parametrize(
    ("field", "inside", "outside"),
    [
        ("master_mm", 35.0, 35.01),
        ("master_mm", -8.0, -8.01),
        ("drill_mm", -8.0, -8.5),
        ("drill_mm", 35.0, 1e6),
        ("force_cmd_n", 50.0, 50.01),
        ("force_cmd_n", -12.0, -12.01),
        ("force_cmd_n", 0.0, 1e30),
        ("velocity_mm_s", MAX_SPEED_MM_S, MAX_SPEED_MM_S * 1.01),
        ("velocity_mm_s", -MAX_SPEED_MM_S, -3e7),
        ("force_est_n", HAND_READING_PEAKS * 50.0, HAND_READING_PEAKS * 50.0 + 0.1),
        ("force_est_n", -HAND_READING_PEAKS * 50.0, -HAND_READING_PEAKS * 50.0 - 0.1),
    ],
)
def test_each_value_is_held_to_the_limits_the_device_announced(
    field: str, inside: float, outside: float
) -> None:
    assert telemetry_problem(_sample(**{field: inside}), OTHER) is None
    problem = telemetry_problem(_sample(**{field: outside}), OTHER)
    assert problem is not None and problem.startswith(f"{field} ")
    # through the watch: a device_fault, the report not recorded
    watch = TelemetryWatch(20.0, 0.0, table_crc32=TABLE, limits=OTHER)
    found = watch.check([_sample(), _sample(tick=20, **{field: outside})], 0.002, False)
    assert found is not None and found.kind == "device_fault" and field in found.message
    assert found.recorded == 1 and not found.trusted


def test_an_end_stops_impact_may_read_as_a_large_hand_force_there_only() -> None:
    # the reaction-force observer takes a stage stopped by its end stop for the hand (660 N on
    # the emulated master at 4.3 m/s): allowed on an end stop (flag or within 1 mm), not in
    # mid-travel
    big = HAND_READING_PEAKS * OTHER.peak_force_n * 4.0
    assert telemetry_problem(_sample(force_est_n=big), OTHER) is not None
    at_end = _sample(force_est_n=-big, master_mm=34.5, faults=int(Fault.TRAVEL_LIMIT))
    assert telemetry_problem(at_end, OTHER) is None
    assert telemetry_problem(replace(at_end, faults=0), OTHER) is None  # rebounded 0.5 mm
    beyond = END_STOP_READING_MULTIPLE * OTHER.peak_force_n + 1.0
    assert telemetry_problem(replace(at_end, force_est_n=beyond), OTHER) is not None


def test_the_session_watch_takes_the_announced_limits() -> None:
    info = DeviceInfo(Version(3, 0, 1, 0, 10_000, 1), OTHER)
    watch = TelemetryWatch.for_session(info, 20.0, TABLE, 0.0)
    # 60 N and 40 mm are within the emulated master's limits, not within this device's
    for change in ({"force_cmd_n": 60.0}, {"master_mm": 40.0}):
        found = TelemetryWatch.for_session(info, 20.0, TABLE, 0.0).check(
            [_sample(**change)], 0.001, False
        )
        assert found is not None and found.kind == "device_fault"
    assert watch.check([_sample()], 0.001, False) is None


@pytest.mark.parametrize("push", ["push:15", "push:-78", "feed:150", "push:77.9", "feed:-200"])
def test_an_honest_device_is_never_refused(push: str) -> None:
    # the emulated master's own extremes (the travel's end stops at 4 m/s, the thermal limit,
    # the wall's impact) stay within the bounds
    slab = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=59.0, stop_depth_mm=3.0)
    result = run_session(SimulatedDevice(), slab, parse_operator(push), 1.3)
    assert result.complete, result.reason


@pytest.mark.parametrize(
    ("lie", "field", "bound"),
    [
        ("force-cmd-150", "max_force_cmd_n", 78.0),
        ("master-95", "max_master_mm", 60.0),
        ("hand-300", "final_hand_est_n", 78.0 * HAND_READING_PEAKS),
    ],
)
def test_the_cli_ends_the_session_and_records_nothing_of_the_lie(
    lie: str,
    field: str,
    bound: float,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    emu = HostileEmulator(lie)
    monkeypatch.setattr(
        "ctdrill.app.rehearse.open_device",
        lambda spec, seed=0: HostDevice(SimLink(emu), token_seed=0),
    )
    out = tmp_path / "out"
    assert main(demo_rehearsal(out, "push:20", "1")) == 3
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "device_fault" in err and "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["complete"] is False and summary["outcome"] == "fault"
    host = summary["faults"][-1]
    assert host["stop_acknowledged"] is True and host["disarm_acknowledged"] is True
    assert abs(summary[field]) <= bound
    assert emu.renderer.state == DeviceState.SAFE


def test_a_lie_while_retracting_the_handle_arms_nothing() -> None:
    # a session that stopped deep leaves the handle there; the next one retracts it first,
    # watching idle telemetry: a report outside the limits there refuses the device (exit 2)
    slab = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=2.0)
    emu = HostileEmulator("master-95", after_s=0.0)
    dev = HostDevice(SimLink(emu), token_seed=0)
    run_session(dev, slab, parse_operator("push:20"), 0.3)  # ends on the lie, the handle deep
    info = dev.hello()
    dev.upload_profile(slab)
    with pytest.raises(DeviceRefused, match="master_mm 95 mm, outside its travel"):
        arm_retracted(dev, limits=info.limits)
    assert emu.renderer.state != DeviceState.CUTTING
