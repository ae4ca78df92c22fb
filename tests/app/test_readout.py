"""Readouts that explain themselves: the model's time to the stop against the simulator's, a
push too weak to cut, and the forces kept apart (hand, device, model)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.app.readout import (
    TIME_TOLERANCE_REL,
    TIME_TOLERANCE_S,
    live_readout,
    push_of,
    stop_timing,
)
from ctdrill.app.rehearse import load_table
from ctdrill.haptics.predict import predict_push
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.run import SessionResult, run_session
from ctdrill.haptics.session import Row, parse_operator
from ctdrill.haptics.sim import SimulatedDevice

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


def _session(table: ProfileTable, push_n: float, duration_s: float) -> SessionResult:
    rows: list[Row] = []
    return run_session(
        SimulatedDevice(),
        table,
        parse_operator(f"push:{push_n:g}"),
        duration_s,
        sink=rows.extend,
        until=lambda: bool(rows) and rows[-1][4] == "stopped",
    )


def test_push_of() -> None:
    assert push_of("push:12") == 12.0
    assert push_of("feed:2") is None and push_of("script:x.csv") is None
    assert push_of("push:nan") is None


def test_predicted_time_on_a_slab_is_depth_over_the_model_feed() -> None:
    # S0 = 4 N, Ke 0.25, 6 N: v = (6/4 - 1)/0.25 = 2 mm/s, 5 mm in 2.5 s; air 1 mm above
    # the slab is reported (no model feed there) and adds nothing to the model's time.
    slab = ProfileTable.slab(s0_n=4.0, top_mm=1.0, bottom_mm=39.0, stop_depth_mm=6.0)
    pred = predict_push(slab, 6.0)
    # the table's linear ramp between the last air row (0.9375 mm) and the first slab row
    # (1.0 mm) is a 0.0625 mm stretch where S0 rises from 0 to 4 N: its exact time is
    # integral Ke S0 / (F - S0) dx = Ke d (-1 - (F/4) ln(1 - 4/F)) with d = 0.0625 mm
    d, ke, f = 0.0625, 0.25, 6.0
    ramp = ke * d * (-1.0 - (f / 4.0) * math.log(1.0 - 4.0 / f))
    assert pred.time_to_stop_s == pytest.approx(5.0 / 2.0 + ramp, rel=1e-4)
    assert pred.air_mm == pytest.approx(0.9375, abs=1e-9)
    assert not pred.too_weak and 0.0 < pred.capped_mm < 0.0625  # the ramp's thin start


def test_a_ramp_stalls_where_s0_reaches_the_push() -> None:
    # S0 rising linearly 0 -> 10 N over 0..10 mm: a 5 N push holds where S0 = 5 N, at 5 mm.
    depth = np.arange(161) * 0.0625
    table = ProfileTable(
        depth_step_mm=0.0625,
        s0_n=np.minimum(depth, 10.0),
        s1_n=np.zeros(161),
        s2_n=np.zeros(161),
        ke_per_mm_s=0.25,
        freqs_hz=np.array([30.0, 60.0]),
        stop_depth_mm=8.0,
    )
    pred = predict_push(table, 5.0)
    assert pred.too_weak and pred.time_to_stop_s == math.inf
    assert pred.stall_depth_mm == pytest.approx(5.0, abs=0.0625 / 16)
    assert "too weak to cut at 5.00 mm" in pred.reasons()[0]
    # A stop short of the stall: t = integral Ke a x / (F - a x) dx, a = 1 N/mm, to 4 mm.
    short = dataclasses.replace(table, stop_depth_mm=4.0)
    exact = 0.25 * (-4.0 - 5.0 * math.log(1.0 - 4.0 / 5.0))
    assert predict_push(short, 5.0).time_to_stop_s == pytest.approx(exact, rel=1e-3)


@pytest.mark.parametrize(
    ("s0_n", "stop_mm", "push_n"),
    [(4.0, 5.0, 6.0), (4.0, 5.0, 12.0), (8.0, 5.0, 10.0), (8.0, 3.0, 30.0), (16.0, 3.0, 20.0)],
)
def test_simulated_time_to_the_stop_agrees_with_the_model_feed(
    s0_n: float, stop_mm: float, push_n: float
) -> None:
    # Through the whole simulated loop (protocol, renderer, DOB/RFOB, plant with friction): a
    # constant push reaches the stop when the model's feed says, within 2 % + 20 ms (the start:
    # the coupling spring compressed to F/k, the front's relaxation; measured 8-39 ms).
    slab = ProfileTable.slab(s0_n=s0_n, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=stop_mm)
    session = _session(slab, push_n, 20.0)
    expected = stop_mm / ((push_n / s0_n - 1.0) / 0.25)
    assert session.time_to_stop_s is not None
    assert session.time_to_stop_s == pytest.approx(
        expected, abs=TIME_TOLERANCE_REL * expected + TIME_TOLERANCE_S
    )
    assert session.time_to_stop_s >= expected  # the start only ever delays it
    timing = stop_timing(slab, push_n, session.time_to_stop_s, 20.0)
    assert timing.agrees and timing.message.endswith(": agrees")
    assert timing.predicted_s == pytest.approx(expected, rel=1e-9)


def test_a_pull_retracts_and_is_not_called_too_weak() -> None:
    # push:-N is the retraction the docs name: the handle moves back and nothing is cut
    slab = ProfileTable.slab(s0_n=8.0, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=5.0)
    session = _session(slab, -10.0, 0.3)
    assert session.time_to_stop_s is None and session.max_drill_mm < 0.05
    assert session.final_master_mm is not None and session.final_master_mm < -1.0
    timing = stop_timing(slab, -10.0, session.time_to_stop_s, 0.3)
    assert timing.agrees and "too weak" not in timing.message
    assert timing.message == (
        "never reached the stop: push -10 N pulls the handle back out of the hole, "
        "so nothing is cut"
    )
    assert "is no push" in stop_timing(slab, 0.0, None, 0.3).message


def test_a_push_too_weak_to_cut_holds_and_says_so() -> None:
    slab = ProfileTable.slab(s0_n=8.0, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=5.0)
    session = _session(slab, 6.0, 1.0)
    assert session.time_to_stop_s is None and session.max_drill_mm < 0.05
    timing = stop_timing(slab, 6.0, session.time_to_stop_s, 1.0)
    assert timing.agrees
    assert "push 6 N too weak to cut at 0.00 mm (S0 = 8.00 N)" in timing.message
    assert session.final_master_mm is not None and session.final_drill_mm is not None
    live = live_readout(
        slab,
        state="cutting",
        master_mm=session.final_master_mm,
        drill_mm=session.final_drill_mm,
        force_n=6.0,
        hand_n=session.final_hand_est_n,
        push_n=6.0,
        plan_feed_mm_s=0.4,
    )
    assert live.kind == "holding" and "push too weak to cut: 6.0 N" in live.status
    assert live.s0_n == 8.0 and live.plan_force_n == pytest.approx(8.0 * (1.0 + 0.25 * 0.4))
    # pushed harder: cutting, the model's feed named
    cut = live_readout(
        slab,
        state="cutting",
        master_mm=1.0,
        drill_mm=0.5,
        force_n=12.0,
        hand_n=12.0,
        push_n=12.0,
        plan_feed_mm_s=0.4,
    )
    assert cut.kind == "cutting" and "2.00 mm/s" in cut.status  # (12/8 - 1)/0.25
    wall = live_readout(
        slab,
        state="stopped",
        master_mm=6.1,
        drill_mm=5.0,
        force_n=12.2,
        hand_n=12.1,
        push_n=12.0,
        plan_feed_mm_s=0.4,
    )
    assert wall.kind == "wall" and "1.10 mm past the stopped drill" in wall.status
    free = live_readout(
        slab,
        state="cutting",
        master_mm=0.5,
        drill_mm=0.5,
        force_n=0.0,
        hand_n=12.0,
        push_n=None,
        plan_feed_mm_s=0.4,
    )
    assert free.kind == "free"


def test_on_the_demo_the_vibration_is_why_the_time_differs() -> None:
    # The demo's table at 12 N: with its cutting vibration the stop comes a few per cent late
    # and the note says why (the vibration); the same table without vibration agrees.
    table = load_table(DEMO / "ct", DEMO / "plan.json").table
    session = _session(table, 12.0, 10.0)
    timing = stop_timing(table, 12.0, session.time_to_stop_s, 10.0)
    assert session.time_to_stop_s is not None
    late = session.time_to_stop_s / timing.predicted_s - 1.0
    assert 0.02 < late < 0.06 and not timing.agrees
    assert "the cutting vibration" in timing.message and "why:" in timing.message
    quiet = dataclasses.replace(table, s1_n=np.zeros(table.n_steps), s2_n=np.zeros(table.n_steps))
    calm = _session(quiet, 12.0, 10.0)
    calm_timing = stop_timing(quiet, 12.0, calm.time_to_stop_s, 10.0)
    assert calm_timing.agrees, calm_timing.message
    assert calm_timing.predicted_s == pytest.approx(timing.predicted_s, rel=1e-12)


def test_rehearse_prints_and_records_the_readouts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["rehearse", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    assert (
        main([*args, "--out", str(tmp_path / "a"), "--operator", "push:20", "--duration-s", "3"])
        == 0
    )
    out = capsys.readouterr().out
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["push_n"] == 20.0 and summary["time_to_stop_agrees"] is True
    assert summary["time_to_stop_s"] == pytest.approx(summary["model_time_to_stop_s"], rel=0.03)
    # the rigid wall: 20 N rests 20 / (11 + 200) N/mm past the stopped drill
    assert summary["hand_past_drill_mm"] == pytest.approx(20.0 / 211.0, abs=0.02)
    assert summary["wall_held"] is True and summary["wall_limits"] is None
    assert "push 20 N: reached the stop after" in out and ": agrees" in out
    assert "hand sits" in out and "past the stopped drill" in out
    assert (
        main([*args, "--out", str(tmp_path / "b"), "--operator", "push:3", "--duration-s", "1"])
        == 0
    )
    out = capsys.readouterr().out
    weak = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert weak["time_to_stop_s"] is None and weak["model_time_to_stop_s"] is None
    assert weak["push_too_weak_at_mm"] == pytest.approx(weak["max_drill_mm"], abs=0.1)
    assert "too weak to cut" in out


def test_a_push_within_the_friction_of_s0_stalls_and_the_note_says_why() -> None:
    # 8.5 N on S0 = 8 N: the model cuts at 0.25 mm/s, but once the stage stops after the
    # impact, the push beats the material by 0.5 N, less than the master's 1 N static friction
    # (its friction model fades to 0 at standstill): the drill holds, and the note says so.
    slab = ProfileTable.slab(s0_n=8.0, top_mm=0.0, bottom_mm=39.0, stop_depth_mm=1.0)
    pred = predict_push(slab, 8.5)
    assert not pred.too_weak and pred.time_to_stop_s == pytest.approx(4.0, rel=1e-9)
    assert pred.friction_depth_mm == 0.0 and pred.friction_s0_n == 8.0
    session = _session(slab, 8.5, 6.0)
    assert session.time_to_stop_s is None and session.max_drill_mm < 0.2
    timing = stop_timing(slab, 8.5, None, 6.0)
    assert not timing.agrees
    assert "by no more than the master's 1 N static friction" in timing.message
    # 1 N above S0 plus a margin cuts (the 12 N slab case above reaches the stop on time)
    assert predict_push(slab, 10.0).friction_depth_mm is None
