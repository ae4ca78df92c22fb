"""SIGTERM and SIGHUP are taken as Ctrl-C (issue 36), with real signals on a real process: an
armed rehearsal (one drill or a sequence) sends STOP and DISARM, writes ``summary.json`` whole
and exits ``128 + signal`` (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP); a batch writes
``status.csv``; an unfinished output an earlier run left is kept and named, never removed
without a word."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.plan.write import save_plan
from ctdrill.interrupts import exit_code_for_signal

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"
DEADLINE_S = 90.0


def _start(args: list[str]) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "ctdrill.app.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
    )


def _wait_for(proc: subprocess.Popen[str], ready: Callable[[], bool]) -> None:
    deadline = time.monotonic() + DEADLINE_S
    while not ready():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the command never got there"
        time.sleep(0.01)


def _armed(out: Path, name: str = "session.csv") -> Callable[[], bool]:
    """True once the staging folder of ``out`` holds telemetry rows (the device is armed)."""

    def ready() -> bool:
        for stage in out.parent.glob(f".{out.name}.ctdrill-new-*"):
            found = list(stage.rglob(name))
            if any(f.stat().st_size > 200 for f in found):
                return True
        return False

    return ready


def _rehearse(out: Path, plan: Path) -> list[str]:
    return [
        "rehearse",
        "--dicom",
        str(DEMO / "ct"),
        "--plan",
        str(plan),
        "--out",
        str(out),
        "--operator",
        "push:6",
        "--duration-s",
        "3600",
    ]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_signal_to_an_armed_rehearsal_stops_the_device_and_writes_the_records(
    tmp_path: Path, sig: signal.Signals
) -> None:
    out = tmp_path / "out"
    proc = _start(_rehearse(out, DEMO / "plan.json"))
    _wait_for(proc, _armed(out))
    os.killpg(proc.pid, sig)
    stdout, stderr = proc.communicate(timeout=DEADLINE_S)
    assert proc.returncode == 128 + sig == exit_code_for_signal(sig.name), stderr
    assert "Traceback" not in stderr + stdout and stderr.count("error:") == 1, stderr
    assert "the device acknowledged STOP and DISARM" in stderr
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["complete"] is False and summary["outcome"] == "interrupted"
    host = [f for f in summary["faults"] if f["source"] == "host"][-1]
    assert host["kind"] == "interrupted" and host["signal"] == sig.name
    assert host["stop_acknowledged"] is True and host["disarm_acknowledged"] is True
    with (out / "session.csv").open(encoding="utf-8") as fh:
        assert len(list(csv.DictReader(fh))) >= 1  # what ran before the signal
    assert not list(tmp_path.glob(".out.*"))  # no staging folder stranded


def test_a_signal_during_a_drill_sequence_writes_every_drills_records(tmp_path: Path) -> None:
    plan = tmp_path / "seq.json"
    drills = (
        DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
        DrillSpec(diameter_mm=2.8, tip_length_mm=0.84),
    )
    save_plan(load_plan(DEMO / "plan.json").with_drills(drills), plan)
    out = tmp_path / "out"
    proc = _start(_rehearse(out, plan))
    _wait_for(proc, _armed(out))
    os.killpg(proc.pid, signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=DEADLINE_S)
    assert proc.returncode == 143, stderr
    assert "Traceback" not in stderr + stdout
    top = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert top["complete"] is False and top["outcome"] == "interrupted"
    host = [f for f in top["faults"] if f["source"] == "host"]
    assert top["drills_run"] == 1 and host[-1]["signal"] == "SIGTERM"
    first = json.loads((out / "drill_1" / "summary.json").read_text(encoding="utf-8"))
    host = [f for f in first["faults"] if f["source"] == "host"]
    assert first["outcome"] == "interrupted" and host[-1]["stop_acknowledged"] is True


def test_an_unfinished_output_of_a_killed_run_is_kept_and_named(tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = _start(_rehearse(out, DEMO / "plan.json"))
    _wait_for(proc, _armed(out))
    os.killpg(proc.pid, signal.SIGKILL)  # no handler can run: the staging folder stays
    proc.communicate(timeout=DEADLINE_S)
    (stage,) = tmp_path.glob(".out.ctdrill-new-*")
    rows = (stage / "session.csv").read_bytes()
    again = _start([*_rehearse(out, DEMO / "plan.json")[:-1], "0.2"])
    _, stderr = again.communicate(timeout=DEADLINE_S)
    assert again.returncode == 0, stderr
    (kept,) = tmp_path.glob("out.unfinished-*")
    assert (kept / "session.csv").read_bytes() == rows  # the killed session's record
    assert f"note: an earlier run (process {proc.pid}, no longer running)" in stderr
    assert str(kept) in stderr
    assert json.loads((out / "summary.json").read_text(encoding="utf-8"))["complete"] is True


def _manifest(folder: Path, n: int) -> Path:
    manifest = folder / "manifest.csv"
    lines = ["id,dicom,plan"]
    lines += [f"r{i:02d},{DEMO / 'ct'},{DEMO / 'plan.json'}" for i in range(1, n + 1)]
    manifest.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return manifest


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_the_batch_starts_its_workers(tmp_path: Path, sig: signal.Signals) -> None:
    # the whole process group gets it (a terminal's Ctrl-C, systemd's SIGTERM) as soon as the
    # batch has made its rows folder, before the worker pool is up: no traceback from the
    # forkserver's imports nor from the pool, status.csv written, every row not run
    out = tmp_path / "out"
    proc = _start(
        ["batch", str(_manifest(tmp_path, 3)), "--out", str(out), "--workers", "2", "--no-plot"]
    )
    _wait_for(proc, (out / "rows").is_dir)
    os.killpg(proc.pid, sig)
    stdout, stderr = proc.communicate(timeout=DEADLINE_S)
    assert proc.returncode == 128 + sig, stderr
    assert "Traceback" not in stderr + stdout, stderr
    assert stderr.startswith("error: interrupted: ") and stderr.count("\n") == 1, stderr
    with (out / "status.csv").open(encoding="utf-8") as fh:
        status = list(csv.DictReader(fh))
    assert len(status) == 3 and {s["status"] for s in status} <= {
        "ok",
        "error: not run (the batch was interrupted)",
    }
