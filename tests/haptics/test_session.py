"""Sessions: operator and fault specifications, fault injection, deterministic replay, CSV."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.session_csv import SessionCsv, session_csv_text
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import (
    SESSION_COLUMNS,
    Operator,
    SessionInputError,
    parse_fault,
    parse_operator,
)
from ctdrill.haptics.sim import SimulatedDevice

TABLE = ProfileTable.slab(
    s0_n=4.0, s1_n=0.3, s2_n=0.1, top_mm=0.5, bottom_mm=39.0, stop_depth_mm=3.0
)


def test_operator_specs() -> None:
    assert parse_operator("push:12.5") == Operator("push", 12.5, spec="push:12.5")
    assert parse_operator("feed:0.4").value == 0.4
    for bad in ["push", "push:", "pull:3", "push:abc", "push:nan", "push:100", "feed:1e6"]:
        with pytest.raises(SessionInputError, match="--operator"):
            parse_operator(bad)


def test_script_operator(tmp_path: Path) -> None:
    script = tmp_path / "hand.csv"
    script.write_text("time_s,force_n\n0,0\n1,10\n2,10\n")
    op = parse_operator(f"script:{script}")
    assert op.force_at_n(-1.0) == 0.0
    assert op.force_at_n(0.5) == pytest.approx(5.0)
    assert op.force_at_n(1.5) == 10.0
    assert op.force_at_n(9.0) == 10.0
    for text, match in [
        ("t,f\n0,1\n", "first line"),
        ("time_s,force_n\n", "no rows"),
        ("time_s,force_n\n0,1\n0,2\n", "increase"),
        ("time_s,force_n\n0,x\n", "force_n at line 2"),
        ("time_s,force_n\n0,200\n", "<= 78"),
    ]:
        script.write_text(text)
        with pytest.raises(SessionInputError, match=match):
            parse_operator(f"script:{script}")
    with pytest.raises(SessionInputError, match="cannot read"):
        parse_operator(f"script:{tmp_path / 'missing.csv'}")


def test_fault_specs() -> None:
    assert parse_fault("link-loss@1.5").time_s == 1.5
    assert parse_fault("delay@0.2:80").duration_ms == 80.0
    assert parse_fault("reset@0").kind == "reset"
    for bad in ["link-loss", "boom@1", "delay@1", "delay@1:-5", "garbage@-1", "reset@1:5"]:
        with pytest.raises(SessionInputError, match="--fault"):
            parse_fault(bad)


def _run(faults: list[str], seed: int = 0, duration_s: float = 0.6) -> tuple[list, dict]:
    rows: list[tuple[float, float, float, float, str]] = []
    result = run_session(
        SimulatedDevice(),
        TABLE,
        parse_operator("push:8"),
        duration_s,
        faults=[parse_fault(f) for f in faults],
        seed=seed,
        sink=rows.extend,
    )
    return rows, result.to_json()


def test_same_seed_same_session_and_garbage_is_harmless() -> None:
    rows_a, sum_a = _run(["garbage@0.1", "garbage@0.2", "delay@0.3:20"], seed=7)
    rows_b, sum_b = _run(["garbage@0.1", "garbage@0.2", "delay@0.3:20"], seed=7)
    assert rows_a == rows_b and sum_a == sum_b
    clean, clean_summary = _run([])
    assert rows_a == clean  # rejected garbage and a 20 ms delay change nothing
    assert sum_a["final_state"] == "cutting"
    assert sum_a["complete"] is True and sum_a["outcome"] == "complete"
    assert sum_a["reason"] is None
    assert [f["kind"] for f in sum_a["faults"]] == ["garbage", "garbage", "delay"]
    assert clean_summary["faults"] == []  # nothing from before ARM (the power-on RESET flag)
    assert sum_a["tick_rate_hz"] == pytest.approx(10_000.0, rel=1e-3)
    assert sum_a["overruns"] == 0
    assert len(rows_a) == 600  # 1 kHz telemetry
    assert rows_a[0][0] == 0.0 and rows_a[0][4] == "cutting"  # the first row is armed


def test_link_loss_and_long_delay_trip_the_watchdog_and_end_the_session() -> None:
    rows, summary = _run(["link-loss@0.3"])
    safe = [r for r in rows if r[4] == "safe"]
    assert safe and all(r[3] == 0.0 for r in safe)
    assert 0.3 < safe[0][0] <= 0.3 + 0.05 + 0.002
    assert rows[-1][0] < 0.3 + 0.05 + 0.011  # the host ended the session within a block
    events = [f for f in summary["faults"] if f["source"] == "device"]
    assert events[0]["flags"] == ["watchdog"]
    assert summary["final_state"] == "safe"
    assert summary["complete"] is False and summary["outcome"] == "fault"
    assert summary["reason"].startswith("device_fault: the device raised watchdog")
    host = summary["faults"][-1]
    assert host["source"] == "host" and host["stop_acknowledged"] is False  # the line is cut
    _, delayed = _run(["delay@0.3:80"])
    assert delayed["final_state"] == "safe"  # 80 ms without a frame: tripped, stays latched
    assert delayed["outcome"] == "fault"
    # the delay ended before the host noticed: STOP and DISARM reached the device
    assert delayed["faults"][-1]["stop_acknowledged"] is True
    assert delayed["faults"][-1]["disarm_acknowledged"] is True


def test_reset_ends_the_session() -> None:
    rows, summary = _run(["reset@0.3"])
    assert rows[-1][0] < 0.3 + 0.011
    kinds = [(f["source"], f["kind"]) for f in summary["faults"]]
    assert kinds == [("injected", "reset"), ("host", "device_reset")]
    assert summary["outcome"] == "fault" and "rebooted" in summary["reason"]


def test_session_csv(tmp_path: Path) -> None:
    path = tmp_path / "session.csv"
    out = SessionCsv(path)
    assert path.read_text() == ",".join(SESSION_COLUMNS) + "\n"  # header flushed at once
    out.write([(0.001, 1.0, 0.5, 2.25, "cutting", 7.125)])
    assert path.read_text().splitlines()[1] == "0.0010,1.00000,0.50000,2.2500,cutting,7.1250"
    out.close()
    assert SESSION_COLUMNS == (
        "time_s",
        "master_mm",
        "drill_mm",
        "force_cmd_n",
        "state",
        "hand_force_n",
    )
    assert session_csv_text([(0.001, 1.0, 0.5, 2.25, "cutting", 7.125)]) == path.read_text()


def test_bad_duration() -> None:
    with pytest.raises(SessionInputError, match="duration"):
        run_session(SimulatedDevice(), TABLE, parse_operator("push:1"), 0.0)


class _CountingRows(tuple[tuple[float, float], ...]):
    """A script's rows that count how many times a row is read."""

    reads = 0

    def __getitem__(self, index: Any) -> Any:
        type(self).reads += 1
        return super().__getitem__(index)


def test_a_long_script_costs_log_time_per_block(tmp_path: Path) -> None:
    # 200 000 rows (a 1M-row script made the host's 10 ms blocks late: a linear scan per block):
    # each lookup reads O(log n) rows, counted (not timed)
    n = 200_000
    script = tmp_path / "long.csv"
    script.write_text("time_s,force_n\n" + "".join(f"{i * 1e-3:.3f},{i % 50}\n" for i in range(n)))
    op = parse_operator(f"script:{script}")
    op = replace(op, script=_CountingRows(op.script))
    values, reads = [], []
    for t in (0.0005, 99.9995, 150.0, 199.9994, 250.0):
        _CountingRows.reads = 0
        values.append(op.force_at_n(t))
        reads.append(_CountingRows.reads)
    # a binary search reads ceil(log2(n + 1)) rows, then the two it interpolates between
    assert max(reads) <= math.ceil(math.log2(n + 1)) + 4, reads
    # row i: (i ms, i % 50 N), linear between rows, held after the last (199.999 s, 49 N)
    assert values == pytest.approx([0.5, 24.5, 0.0, 49.0, 49.0])
