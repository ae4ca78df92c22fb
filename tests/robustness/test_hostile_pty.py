"""A lying device over a real pseudo-terminal (issue 29), as a person would meet it.

The device is :mod:`tests.haptics.hostile` in a process of its own on a pty (real time); the
host is ``ctdrill rehearse --device serial:PTY``. Each class (a number that is not finite, an
undefined state, device time jumping near 2^64) ends with exit 3, a whole and valid
``summary.json``, and the STOP reaching the device after its first lie (the device measures
how long after on its own clock; the assertions do not depend on it). A run whose host, starved
by a loaded machine, let the watchdog trip before the lie (its own heartbeat gap explains it)
is run again on a fresh device.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.cli import main
from ctdrill.haptics.protocol import DeviceState, Fault
from tests.haptics.emulator_process import REAL_TIME_ATTEMPTS, ROOT, demo_rehearsal, host_late
from tests.haptics.hostile import TELEMETRY_LIES
from tests.robustness.test_hostile_device import check_fault_records


@contextmanager
def hostile_process(link: Path, lie: str, report: Path) -> Iterator[subprocess.Popen[str]]:
    """The hostile device on a pty linked at ``link``; its report is written when it ends."""
    proc = subprocess.Popen(
        [
            *(sys.executable, "-m", "tests.haptics.hostile"),
            *("--pty-link", str(link), "--lie", lie, "--report", str(report)),
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith(f"emulating on {link}")
        yield proc
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err


@pytest.mark.timeout(240)
@pytest.mark.parametrize("lie", ["state-5", "nan-force", "time-jump-2-64"])
def test_a_lying_device_on_a_pty_ends_the_rehearsal_with_exit_3(
    lie: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    late: list[str] = []
    for attempt in range(REAL_TIME_ATTEMPTS):
        link, out = tmp_path / f"dev-{attempt}", tmp_path / f"out-{attempt}"
        report = tmp_path / f"report-{attempt}.json"
        with hostile_process(link, lie, report):
            code = main(demo_rehearsal(out, "push:20", "3", "--device", f"serial:{link}"))
        err = capsys.readouterr().err
        ended = json.loads((out / "summary.json").read_text())
        reason, gap = ended["reason"] or "", ended["max_heartbeat_gap_s"]
        if not host_late("raised watchdog" in reason, gap):
            break
        late.append(f"{reason} (host heartbeat gap {gap * 1e3:.0f} ms)")  # starved: run again
    else:
        raise AssertionError(f"the host was late in every run: {late}")
    assert code == 3, err
    assert err.count("error:") == 1 and "Traceback" not in err
    summary = check_fault_records(out, TELEMETRY_LIES[lie])
    device: dict[str, Any] = json.loads(report.read_text())
    assert device["state"] == DeviceState.SAFE and device["faults"] & Fault.HOST_STOP
    assert device["first_lie_at"] is not None and device["stop_at"] is not None
    assert device["stop_at"] > device["first_lie_at"]  # (how long after: docs/protocol.md)
    assert summary["faults"][-1]["stop_acknowledged_after_s"] >= 0.0
