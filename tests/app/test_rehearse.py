"""``ctdrill rehearse`` on the demo phantom: files, contract, stop, faults, replay, refusals."""

from __future__ import annotations

import csv
import hashlib
import itertools
import json
import subprocess
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from ctdrill.haptics.tick import TICK_HZ
from tests.haptics.emulator_process import HostLate, host_late, with_fresh_emulator

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


def _rehearse(out: Path, *extra: str, operator: str = "push:20", duration: str = "2") -> int:
    return main(
        [
            "rehearse",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(out),
            "--operator",
            operator,
            "--duration-s",
            duration,
            *extra,
        ]
    )


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def test_rehearse_writes_the_contract_files_and_stops_at_the_margin(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _rehearse(out, operator="push:78", duration="3") == 0
    text = (out / "session.csv").read_text()
    assert text.splitlines()[0] == "time_s,master_mm,drill_mm,force_cmd_n,state,hand_force_n"
    rows = _rows(out / "session.csv")
    assert len(rows) == 3000
    summary = json.loads((out / "summary.json").read_text())
    for key in ("stop_depth_mm", "max_drill_mm", "tick_rate_hz", "overruns", "faults"):
        assert key in summary
    assert summary["complete"] is True and summary["reason"] is None
    # nothing from before ARM (the power-on RESET flag); at 78 N the limits engage
    flags = {f for e in summary["faults"] for f in e["flags"]}
    assert {e["source"] for e in summary["faults"]} == {"device"} and "reset" not in flags
    assert summary["stop_reason"] == "margin"
    assert summary["calibration"] == "bone-illustrative" and summary["calibration_illustrative"]
    stop = summary["stop_depth_mm"]
    assert 0.0 < stop < summary["planned_depth_mm"]
    drill = [float(r["drill_mm"]) for r in rows]
    assert max(drill) <= stop + 1e-4  # CSV rounding to 1e-5 mm
    assert max(drill) == pytest.approx(stop, abs=1e-4)  # 78 N reaches the stop...
    assert float(rows[-1]["master_mm"]) > stop  # ...while the hand is pushed past it
    assert rows[-1]["state"] == "stopped"
    assert {r["state"] for r in rows} <= {"cutting", "stopped"}
    assert all(0.0 <= float(r["force_cmd_n"]) <= 78.0 for r in rows)
    assert summary["tick_rate_hz"] == pytest.approx(10_000.0, rel=1e-3)
    assert summary["overruns"] == 0


def test_same_seed_replays_identically_and_link_loss_ends_with_exit_3(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    faults = ["--fault", "garbage@0.2", "--fault", "link-loss@0.5", "--seed", "3"]
    assert _rehearse(tmp_path / "a", *faults, duration="0.8") == 3
    assert _rehearse(tmp_path / "b", *faults, duration="0.8") == 3
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and all(e.startswith("error: the session ended early") for e in err)
    assert "STOP and DISARM were not sent" in err[0]  # the injected link loss cut the line
    a = (tmp_path / "a" / "session.csv").read_bytes()
    assert a == (tmp_path / "b" / "session.csv").read_bytes()
    rows = _rows(tmp_path / "a" / "session.csv")
    first_safe = next(float(r["time_s"]) for r in rows if r["state"] == "safe")
    assert 0.5 < first_safe <= 0.552
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["final_state"] == "safe"
    assert summary["complete"] is False and summary["outcome"] == "fault"
    assert "watchdog" in summary["reason"]
    assert [f["kind"] for f in summary["faults"] if f["source"] == "injected"] == [
        "garbage",
        "link-loss",
    ]


def test_a_failing_device_leaves_the_previous_session_intact(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _rehearse(out, duration="0.2") == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(before) == {"session.csv", "summary.json", "table.json"}
    # the device cannot be opened: exit 2, nothing of the last session touched
    assert _rehearse(out, "--device", "serial:/nonexistent/tty", duration="0.2") == 2
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    # a session that ends on a fault replaces it whole, with its summary
    assert _rehearse(out, "--fault", "reset@0.1", duration="0.3") == 3
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and "rebooted" in summary["reason"]
    assert summary["calibration_illustrative"] is True
    assert (out / "session.csv").read_bytes() != before["session.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no staging left over


def test_script_operator_drives_the_session(tmp_path: Path) -> None:
    script = tmp_path / "hand.csv"
    script.write_text("time_s,force_n\n0,0\n0.5,0\n1.0,30\n")
    out = tmp_path / "out"
    assert _rehearse(out, operator=f"script:{script}", duration="1.2") == 0
    rows = _rows(out / "session.csv")
    early = [float(r["drill_mm"]) for r in rows if float(r["time_s"]) < 0.5]
    assert max(early) < 0.01  # no hand force yet: the drill stays at the entry
    assert float(rows[-1]["drill_mm"]) > 0.1  # 30 N cuts
    assert float(rows[-1]["force_cmd_n"]) == pytest.approx(30.0, abs=3.0)
    summary = json.loads((out / "summary.json").read_text())
    # named by its content's hash, never by its path (a patient-named folder stays out)
    digest = hashlib.sha256(script.read_bytes()).hexdigest()[:16]
    assert summary["operator"] == f"script:sha256={digest}"
    assert str(tmp_path) not in (out / "summary.json").read_text()


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        ((), {"operator": "shove:3"}, "--operator"),
        (("--fault", "meteor@1"), {}, "--fault"),
        (("--device", "usb"), {}, "--device"),
        (("--device", "serial:/nonexistent/tty"), {}, "cannot open serial port"),
        ((), {"duration": "-1"}, "--duration-s"),
    ],
)
def test_bad_input_is_one_error_line_and_exit_2(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    args: tuple[str, ...],
    kwargs: dict[str, str],
    match: str,
) -> None:
    assert _rehearse(tmp_path / "out", *args, **kwargs) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and match in err and err.count("\n") == 1
    assert "Traceback" not in err


@pytest.mark.timeout(180)
def test_rehearse_over_a_serial_link_to_the_emulator(tmp_path: Path) -> None:
    def case(link: Path, _emulator: subprocess.Popen[str]) -> None:
        out = link.with_name(f"{link.name}-out")
        code = _rehearse(out, "--device", f"serial:{link}", duration="1")
        summary = json.loads((out / "summary.json").read_text())
        reason, gap = summary["reason"] or "", summary["max_heartbeat_gap_s"]
        if host_late("raised watchdog" in reason, gap):  # a loaded machine starved this host
            raise HostLate(f"{reason} (host heartbeat gap {gap * 1e3:.0f} ms)")
        assert code == 0, reason
        rows = _rows(out / "session.csv")
        # real time: about 1000 rows of telemetry, fewer when a busy machine slows the
        # emulator's clock; never one missing (1 kHz of device time) and never ahead of the
        # host's clock by more than the emulator's catch-up of a stall
        times = [float(r["time_s"]) for r in rows]
        assert len(rows) > 1 and all(abs(b - a - 1e-3) < 1e-6 for a, b in itertools.pairwise(times))
        assert summary["max_drill_mm"] <= summary["device_stop_depth_mm"]
        assert 0.0 < summary["tick_rate_hz"] < 1.5 * TICK_HZ
        assert summary["device"] == f"serial:{link}"

    with_fresh_emulator(tmp_path, case)
