"""Exam mode and the human operator on the demo: ordered overshoots, the guard, the summary."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.app.rehearse import RehearsalTable, load_table
from ctdrill.app.trainee.exam import EXAM_REACH_MM, plan_hash
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS, Assessment, Assessor
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import parse_operator
from ctdrill.haptics.sim import SimulatedDevice
from ctdrill.imaging.plan.load import load_one_plan

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"
REACTIONS_MS = (50.0, 150.0, 300.0)


@pytest.fixture(scope="module")
def tables() -> dict[str, RehearsalTable]:
    plan = DEMO / "plan.json"
    return {
        "exam": load_table(DEMO / "ct", plan, exam=True),
        "guard": load_table(DEMO / "ct", plan),
    }


def _session(loaded: RehearsalTable, react_ms: float, duration_s: float) -> Assessment:
    assessor = Assessor(loaded.context, loaded.table)
    operator = parse_operator(f"human:force=12,react_ms={react_ms:g}")
    run_session(SimulatedDevice(), loaded.table, operator, duration_s, on_samples=assessor.add)
    return assessor.result()


def test_the_exam_table_reaches_beyond_the_plan(tables: dict[str, RehearsalTable]) -> None:
    exam, guard = tables["exam"], tables["guard"]
    assert guard.table.stop_depth_mm == pytest.approx(10.8, abs=1e-3)  # the margin's wall
    assert exam.exam is not None and exam.exam.basis == "beyond_plan"
    assert exam.table.stop_depth_mm == pytest.approx(
        12.6 + EXAM_REACH_MM, abs=1e-4
    )  # drilled: apex + tip
    # the same force table along the plan, and the canal's clearance past it (vertical drill,
    # canal top 12.8 mm down: clearance 12.8 - x, negative inside)
    n = guard.table.n_steps
    assert np.array_equal(exam.table.s0_n[:n], guard.table.s0_n)
    ctx = exam.context
    assert ctx.max_safe_depth_mm == pytest.approx(10.8, abs=1e-3)
    assert ctx.goal_depth_mm == pytest.approx(10.8, abs=1e-3)
    assert ctx.clearance_at_mm(14.0) == pytest.approx(-1.2, abs=0.02)


def test_later_reactions_overshoot_deeper_and_the_guard_holds(
    tables: dict[str, RehearsalTable],
) -> None:
    exam = [_session(tables["exam"], ms, 3.5) for ms in REACTIONS_MS]
    overshoot = [a.overshoot_mm for a in exam]
    # 12 N breaks into the canal (at 13.4 mm, 2.74 s), then cuts the bone below it until the
    # hand lets go: each 100 ms more is about 0.4 mm deeper
    assert overshoot[0] < overshoot[1] < overshoot[2]
    assert overshoot[2] - overshoot[0] > 0.8
    for ms, a in zip(REACTIONS_MS, exam, strict=True):
        assert a.breach and a.canal_entered and a.time_in_margin_s > 0.0
        assert a.reaction_ms is not None and ms <= a.reaction_ms <= ms + 15.0
        assert a.score < 45.0
    assert [a.score for a in exam] == sorted((a.score for a in exam), reverse=True)
    for ms in REACTIONS_MS:
        a = _session(tables["guard"], ms, 2.6)
        assert not a.breach and a.overshoot_mm == 0.0 and a.time_in_margin_s == 0.0
        assert not a.canal_entered and a.reaction_ms is None and a.wall_contacts >= 1
        # measured against the goal (the guard's 10.8 mm, not the planned 12.6 mm): the
        # perfect guarded session scores 100, whatever the case's plan asks beyond the margin
        assert a.goal_depth_mm == pytest.approx(10.8, abs=1e-3) and a.attempted
        assert a.depth_error_mm == pytest.approx(0.0, abs=1e-3) and a.wall_contacts == 1
        assert a.score == 100.0
        # the hand pushed 12 N: its peak is that push (the observer reads 16 N for a
        # millisecond where the handle meets the wall; the 50 ms mean does not)
        assert a.peak_hand_force_n == pytest.approx(12.0, abs=0.5)


def _rehearse(out: Path, *extra: str) -> int:
    return main(
        [
            "rehearse",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(out),
            "--duration-s",
            "3.2",
            *extra,
        ]
    )


def test_exam_summary_from_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "exam"
    assert _rehearse(out, "--exam", "--operator", "human:force=12,react_ms=100") == 0
    stdout = capsys.readouterr().out
    assert "(exam: beyond_plan)" in stdout and "assessment: score" in stdout
    text = (out / "summary.json").read_text()
    summary = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in summary.json"))
    assert tuple(summary["assessment"]) == ASSESSMENT_FIELDS
    a = summary["assessment"]
    assert a["breach"] is True and a["canal_entered"] is True and 0.0 <= a["score"] < 45.0
    assert a["overshoot_mm"] == pytest.approx(summary["max_drill_mm"] - 10.8, abs=2e-3)
    assert a["depth_error_mm"] == pytest.approx(summary["max_drill_mm"] - 10.8, abs=1e-3)
    assert a["goal_depth_mm"] == pytest.approx(10.8, abs=1e-3) and a["attempted"] is True
    assert summary["exam"]["enabled"] is True and summary["exam"]["stop_basis"] == "beyond_plan"
    assert summary["device_stop_depth_mm"] == pytest.approx(22.6, abs=1e-4)
    assert summary["plan_sha256"] == plan_hash(load_one_plan([DEMO / "plan.json"]))
    assert summary["recorded_at"].endswith("+00:00")


def test_on_the_robot_the_exam_wall_stands_at_the_canal_surface() -> None:
    robot = load_table(DEMO / "ct", DEMO / "plan.json", exam=True, exam_surface=True)
    assert robot.exam is not None and robot.exam.basis == "canal_surface"
    # the canal's roof is 12.8 mm down the vertical drill (clearance 12.8 - x): the wall stands
    # at the last grid depth that does not cross it, never inside
    stop = robot.table.stop_depth_mm
    assert 12.8 - 0.05 - 1e-6 <= stop <= 12.8 + 1e-6
    assert robot.context.clearance_at_mm(stop) >= 0.0
    assert robot.context.max_safe_depth_mm == pytest.approx(10.8, abs=1e-3)
    a = _session(robot, 150.0, 3.0)  # a 12 N push that meets the wall at the canal
    assert a.breach and not a.canal_entered
    assert a.overshoot_mm == pytest.approx(stop - 10.8, abs=0.01)
    assert 0.0 < a.score < 45.0  # a breach of the margin, measured as in simulation


@pytest.mark.timeout(180)
def test_exam_runs_on_the_robot_with_its_wall_at_the_canal(tmp_path: Path) -> None:
    from tests.haptics.emulator_process import HostLate, host_late, with_fresh_emulator

    def case(link: Path, _emulator: object) -> None:
        out = link.with_name(f"{link.name}-out")
        code = _rehearse(out, "--exam", "--operator", "push:20", "--device", f"serial:{link}")
        summary = json.loads((out / "summary.json").read_text())
        reason, gap = summary["reason"] or "", summary["max_heartbeat_gap_s"]
        if host_late("raised watchdog" in reason, gap):  # a loaded machine starved this host
            raise HostLate(f"{reason} (host heartbeat gap {gap * 1e3:.0f} ms)")
        assert code == 0, reason
        assert summary["exam"]["enabled"] and summary["exam"]["stop_basis"] == "canal_surface"
        stop = summary["exam"]["stop_depth_mm"]
        assert 12.75 - 1e-4 <= stop <= 12.8 + 1e-4
        assert summary["max_drill_mm"] <= stop + 1e-3  # the device's wall held at the canal
        a = summary["assessment"]
        assert a["breach"] is True and a["canal_entered"] is False
        assert a["overshoot_mm"] == pytest.approx(summary["max_drill_mm"] - 10.8, abs=2e-3)

    with_fresh_emulator(tmp_path, case)


def test_bad_human_grammar_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = _rehearse(tmp_path / "x", "--operator", "human:force=12,react_ms=soon")
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert err[0].startswith("error: --operator") and "react_ms" in err[0]


@pytest.mark.parametrize("operator", ["human:force=20,react_ms=150", "push:-10"])
def test_letting_go_or_pulling_back_ends_the_session_well(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], operator: str
) -> None:
    # A person who meets the wall at 20 N and lets go 150 ms later: the handle rests at the
    # stopped drill (it used to be thrown back and coast to the travel end at 1.85 s:
    # travel_limit). A hand pulling back from the start retracts freely to the travel end; the
    # release damper, which the end stop's jolt could wake, adds no force limit to it.
    out = tmp_path / "session"
    assert _rehearse(out, "--operator", operator) == 0
    capsys.readouterr()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True
    flags = {f for event in summary["faults"] for f in event.get("flags", [])}
    if operator.startswith("human"):
        assert summary["faults"] == [] and summary["final_state"] == "stopped"
        assert summary["final_master_mm"] == pytest.approx(10.8, abs=0.01)
        assert summary["wall_held"] is True and summary["assessment"]["wall_contacts"] == 1
    else:
        assert flags == {"travel_limit"} and summary["max_drill_mm"] == 0.0
        assert summary["final_master_mm"] == pytest.approx(-20.0, abs=1e-3)
