"""A device that lies (issue 29): the host decides from its own clock and its own bounds.

Every class of lie a device can tell in its reports (non-finite numbers, an undefined state or
fault flag, another table, device time that runs backwards, stands still, jumps near 2^64 or
runs ahead of the host's clock, an undecipherable FAULT report, silence) ends the rehearsal with
STOP and DISARM, a whole and valid ``summary.json`` (``complete`` false, the reason, no NaN or
Infinity) and exit code 3, through the CLI and through the Python API; lies told at HELLO
(LIMITS or VERSION outside the host's bounds) are refused before anything is uploaded (exit 2).
The device is :class:`tests.haptics.hostile.HostileEmulator`, in-process here; over a real
pseudo-terminal in ``test_hostile_pty.py``.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.cli import main
from ctdrill.app.rehearse import rehearse
from ctdrill.haptics.device import DeviceError
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState, Fault
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import parse_operator
from ctdrill.haptics.sim import SimLink
from tests.haptics.emulator_process import DEMO, demo_rehearsal
from tests.haptics.hostile import HELLO_LIES, TELEMETRY_LIES, HostileEmulator

SLAB = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=20.0)


def strict_json(path: Path) -> dict[str, Any]:
    """``path`` parsed as JSON proper: NaN, Infinity and -Infinity are refused."""

    def refuse(constant: str) -> None:
        raise AssertionError(f"{path.name} holds {constant}: not JSON")

    data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)
    return data


def _finite_everywhere(value: Any) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_finite_everywhere(v) for v in value.values())
    if isinstance(value, list):
        return all(_finite_everywhere(v) for v in value)
    return True


def _behind(monkeypatch: pytest.MonkeyPatch, lie: str) -> HostileEmulator:
    emu = HostileEmulator(lie)
    monkeypatch.setattr(
        "ctdrill.app.rehearse.open_device",
        lambda spec, seed=0: HostDevice(SimLink(emu), token_seed=0),
    )
    return emu


def _args(out: Path) -> list[str]:
    return demo_rehearsal(out, "push:20", "1")


def check_fault_records(out: Path, kind: str) -> dict[str, Any]:
    """The records of a session the host ended on ``kind``: whole, valid, nothing untrusted."""
    summary = strict_json(out / "summary.json")
    assert summary["complete"] is False and summary["outcome"] == "fault"
    assert summary["reason"].startswith(f"{kind}: "), summary["reason"]
    host = summary["faults"][-1]
    assert host["source"] == "host" and host["kind"] == kind
    assert host["stop_acknowledged"] is True and host["disarm_acknowledged"] is True
    assert _finite_everywhere(summary)
    with (out / "session.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert rows, "the trusted part of the session is recorded"
    names = {"idle", "cutting", "stopped", "safe"}
    for row in rows:
        assert row["state"] in names
        assert all(math.isfinite(float(row[k])) for k in ("master_mm", "drill_mm", "force_cmd_n"))
    times = [float(r["time_s"]) for r in rows]
    assert times == sorted(times) and times[-1] < 1.0
    return summary


@pytest.mark.parametrize("lie", sorted(TELEMETRY_LIES))
def test_a_lying_device_ends_the_cli_rehearsal_with_exit_3(
    lie: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    emu = _behind(monkeypatch, lie)
    out = tmp_path / "out"
    assert main(_args(out)) == 3
    err = capsys.readouterr().err
    kind = TELEMETRY_LIES[lie]
    assert err.startswith(f"error: the session ended early ({kind}: "), err
    assert err.count("error:") == 1 and "Traceback" not in err
    assert "the device acknowledged STOP and DISARM" in err
    check_fault_records(out, kind)
    # the STOP reached the device: it is safe, its force off
    assert emu.renderer.state == DeviceState.SAFE and emu.renderer.faults & Fault.HOST_STOP
    assert emu.renderer.force_cmd_n == 0.0


@pytest.mark.parametrize("lie", sorted(TELEMETRY_LIES))
def test_a_lying_device_ends_the_python_session(lie: str) -> None:
    emu = HostileEmulator(lie, after_s=0.1)
    dev = HostDevice(SimLink(emu), token_seed=0)
    rows: list[tuple[float, float, float, float, str]] = []
    result = run_session(dev, SLAB, parse_operator("push:10"), 1.0, sink=rows.extend)
    kind = TELEMETRY_LIES[lie]
    assert not result.complete and result.outcome == "fault"
    assert result.reason is not None and result.reason.startswith(f"{kind}: ")
    assert result.faults[-1]["stop_acknowledged"] is True
    json.dumps(result.to_json(), allow_nan=False)  # nothing untrusted folded in
    assert rows and all(math.isfinite(r[1]) and r[4] != "?" for r in rows)
    assert emu.renderer.state == DeviceState.SAFE


def test_the_python_rehearsal_writes_valid_records(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _behind(monkeypatch, "inf-master")
    out = tmp_path / "out"
    summary = rehearse(
        dicom=DEMO / "ct", plan=DEMO / "plan.json", out=out, operator="push:20", duration_s=1.0
    )
    assert summary == strict_json(out / "summary.json")
    check_fault_records(out, "device_fault")
    assert "non-finite master_mm" in summary["reason"]


@pytest.mark.parametrize("lie", HELLO_LIES)
def test_a_device_announcing_limits_outside_the_bounds_is_refused(
    lie: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    emu = _behind(monkeypatch, lie)
    out = tmp_path / "out"
    assert main(_args(out)) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: device on sim announced ")
    assert "refused" in err and "Traceback" not in err
    assert not out.exists()  # nothing written
    assert not emu.renderer.has_profile  # nothing uploaded
    with pytest.raises(DeviceError, match=r"announced (LIMITS|VERSION)"):
        HostDevice(SimLink(HostileEmulator(lie)), token_seed=0).hello()
