"""The session's assessment on telemetry whose answers are known, and the score's properties."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.haptics.assessment import (
    ASSESSMENT_FIELDS,
    AssessmentContext,
    Assessor,
    combine_assessments,
    score_of,
)
from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState

CUT, STOP = int(DeviceState.CUTTING), int(DeviceState.STOPPED)
TABLE = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=20.0)


def _sample(t: float, master: float, drill: float, force: float, hand: float, state: int) -> Any:
    return TelemetrySample(t, round(t * 1e4), master, drill, 0.0, force, hand, state, 0, 0)


def _context(**kw: Any) -> AssessmentContext:
    depth = np.linspace(0.0, 30.0, 601)
    base: dict[str, Any] = {
        "planned_depth_mm": 10.0,
        "max_safe_depth_mm": 8.0,
        "goal_depth_mm": 8.0,
        "clearance_depth_mm": depth,
        "clearance_mm": 10.0 - depth,
    }
    return AssessmentContext(**(base | kw))


def test_a_steady_feed_and_a_margin_crossing_measured_exactly() -> None:
    # 1 kHz: the drill advances 2 mm/s from 0 to 9 mm (4.5 s), then holds at 9 mm for 1 s.
    a = Assessor(_context(), TABLE)
    t = np.arange(0, 5501) / 1000.0
    drill = np.minimum(2.0 * t, 9.0)
    a.add([_sample(ti, d + 0.5, d, 6.0, 6.0, CUT) for ti, d in zip(t, drill, strict=True)])
    r = a.result()
    assert r.depth_error_mm == pytest.approx(1.0)  # against the goal, 8 mm
    assert r.goal_depth_mm == 8.0 and r.attempted
    assert r.breach and r.overshoot_mm == pytest.approx(1.0)
    # beyond 8 mm from t = 4.0 s to the last cut at 4.5 s (the held second does not count)
    assert r.time_in_margin_s == pytest.approx(0.5, abs=0.0015)
    assert r.time_to_planned_s == pytest.approx(4.0, abs=0.0015)  # the goal: 8 mm
    assert not r.canal_entered  # clearance 10 - 9 = 1 mm
    assert r.feed_cv == pytest.approx(0.0, abs=1e-6)  # the held second is not cutting
    assert r.peak_hand_force_n == 6.0 and r.mean_hand_force_n == 6.0
    assert r.wall_contacts == 0 and r.peak_wall_force_n == 0.0 and r.reaction_ms is None
    assert r.score == score_of(r.to_json()) and r.score < 45.0


def test_feed_variation_contacts_and_reaction() -> None:
    # Feeds alternate 1 and 3 mm/s in 0.1 s windows: mean 2, standard deviation 1: cv 0.5.
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=4.0, stop_depth_mm=6.0)
    a = Assessor(_context(max_safe_depth_mm=20.0, goal_depth_mm=6.0), table)
    samples, d = [], 0.0
    for i in range(1601):  # 1.6 s; the session's time starts at the first sample
        samples.append(_sample(i / 1000.0, d + 0.2, d, 5.0, 9.0, CUT))
        d += (1.0 if i // 100 % 2 == 0 else 3.0) / 1000.0
    a.add(samples)
    assert a.result().feed_cv == pytest.approx(0.5, rel=1e-3)
    assert a.result().reaction_ms is None  # still inside the bone: no breakthrough yet


def test_reaction_and_wall_contacts() -> None:
    # The drill crosses the table's breakthrough (its far face, 4 mm + one row) at 2 mm/s; the
    # device reads the hand below 1 N from 250 ms later; then two separate touches of the wall.
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=4.0, stop_depth_mm=6.0)
    table = ProfileTable(**{**table.__dict__, "goal_depth_mm": 4.0})  # the slab's far face
    a = Assessor(_context(max_safe_depth_mm=20.0, goal_depth_mm=6.0), table)
    bt = a.breakthrough_mm
    assert bt is not None and 4.0 < bt <= 4.0625 + 1e-9
    t_cross = bt / 2.0
    samples = []
    for i in range(2800):
        t = i / 1000.0
        hand = 9.0 if t < t_cross + 0.25 - 1e-9 else 0.2
        samples.append(_sample(t, 2.0 * t + 0.2, min(2.0 * t, 5.5), 5.0, hand, CUT))
    a.add(samples)
    # pushing on the wall for 0.1 s, letting go for 0.1 s, twice (1 kHz)
    walls = [(6.1, 7.0, 9.0), (6.0, 0.0, 0.0), (6.3, 12.0, 9.0), (6.0, 0.0, 0.0)]
    for k, (master, force, hand) in enumerate(walls):
        t0 = 2.8 + 0.1 * k
        a.add([_sample(t0 + 0.001 * (i + 1), master, 6.0, force, hand, STOP) for i in range(100)])
    r = a.result()
    # each push on the wall lasts while the hand's 50 ms mean is 1 N or more and presses while
    # the reading is: 0.1 s each, less up to 10 ms while the mean rises again the second time
    assert 2 * 0.099 - 0.012 <= r.wall_press_s <= 2 * 0.099 + 0.001
    assert r.wall_overrun_mm == pytest.approx(0.3, abs=1e-6)
    assert r.reaction_ms == pytest.approx(250.0, abs=1.01)  # to a millisecond sample
    assert r.wall_contacts == 2 and r.peak_wall_force_n == 12.0
    assert r.peak_hand_force_n == 9.0 and r.mean_hand_force_n == 9.0  # while on the handle


def test_the_hand_peak_is_a_push_not_an_observer_transient() -> None:
    # 1 kHz: a steady 6 N reading with a 3 ms transient of 30 N (as the observer reads where
    # the handle meets the wall), then a push of 12 N held for 0.2 s. Over 50 ms windows the
    # transient adds 24 N * 3 / 50 = 1.44 N; the held push reads 12 N.
    a = Assessor(_context(), TABLE)
    hand = [6.0] * 300 + [30.0] * 3 + [6.0] * 297 + [12.0] * 200
    a.add([_sample(i / 1000.0, 1.0, 0.5, 6.0, f, CUT) for i, f in enumerate(hand[:600])])
    assert a.result().peak_hand_force_n == pytest.approx(6.0 + 24.0 * 3 / 50, abs=1e-9)
    a.add([_sample(i / 1000.0, 1.0, 0.5, 6.0, f, CUT) for i, f in enumerate(hand) if i >= 600])
    assert a.result().peak_hand_force_n == pytest.approx(12.0, abs=1e-9)
    # a session armed for less than 50 ms: the mean of its readings
    short = Assessor(_context(), TABLE)
    short.add([_sample(i / 1000.0, 1.0, 0.5, 6.0, 4.0 + (i % 2), CUT) for i in range(20)])
    assert short.result().peak_hand_force_n == pytest.approx(4.5, abs=1e-9)


@st.composite
def assessments(draw: Any, breach: bool) -> dict[str, Any]:
    pos = st.floats(0.0, 100.0, allow_nan=False)
    return {
        "depth_error_mm": draw(st.floats(-50.0, 50.0, allow_nan=False)),
        "overshoot_mm": draw(st.floats(0.001, 40.0)) if breach else 0.0,
        "breach": breach,
        "time_in_margin_s": draw(pos) if breach else 0.0,
        "canal_entered": draw(st.booleans()) if breach else False,
        "peak_hand_force_n": draw(st.floats(0.0, 78.0)),
        "mean_hand_force_n": draw(st.floats(0.0, 78.0)),
        "time_to_planned_s": draw(st.none() | pos),
        "feed_cv": draw(st.none() | st.floats(0.0, 1e3)),
        "reaction_ms": draw(st.none() | st.floats(0.0, 1e6)),
        "wall_contacts": draw(st.integers(0, 10_000)),
        "peak_wall_force_n": draw(st.floats(0.0, 78.0)),
        "goal_depth_mm": draw(st.floats(0.5, 30.0)),
        "attempted": True,
        "hand_force_cv": draw(st.none() | st.floats(0.0, 10.0)),
        "plunge_mm": draw(st.floats(0.0, 20.0)),
        "wall_press_s": draw(pos),
        "wall_overrun_mm": draw(st.floats(0.0, 80.0)),
        "display_lag_ms": draw(st.none() | pos),
        "display_lagged": draw(st.booleans()),
    }


@settings(max_examples=150, deadline=None)
@given(assessments(breach=True), assessments(breach=False), assessments(breach=False))
def test_a_breach_scores_below_any_attempted_session_that_kept_the_margin(
    bad: dict[str, Any], good: dict[str, Any], idle: dict[str, Any]
) -> None:
    lo, hi = score_of(bad), score_of(good)
    assert 0.0 <= lo < hi <= 100.0 and math.isfinite(lo)
    # a session that never reached the goal region scores below both, reported apart
    assert score_of(idle | {"attempted": False}) == 0.0 <= lo
    deeper = bad | {"overshoot_mm": bad["overshoot_mm"] + 1.0}
    assert score_of(deeper) <= lo
    json.dumps(good | {"score": hi}, allow_nan=False)


def test_the_fields_are_the_contract() -> None:
    assert ASSESSMENT_FIELDS == (
        "depth_error_mm",
        "overshoot_mm",
        "breach",
        "time_in_margin_s",
        "canal_entered",
        "peak_hand_force_n",
        "mean_hand_force_n",
        "time_to_planned_s",
        "feed_cv",
        "reaction_ms",
        "wall_contacts",
        "peak_wall_force_n",
        "goal_depth_mm",
        "attempted",
        "hand_force_cv",
        "plunge_mm",
        "wall_press_s",
        "wall_overrun_mm",
        "display_lag_ms",
        "display_lagged",
        "score",
    )
    perfect = dict.fromkeys(ASSESSMENT_FIELDS[:-1], 0.0) | {
        "breach": False,
        "canal_entered": False,
        "attempted": True,
        "display_lagged": False,
        "wall_contacts": 0,
        "feed_cv": None,
        "reaction_ms": None,
        "hand_force_cv": None,
        "display_lag_ms": None,
    }
    assert score_of(perfect) == 100.0
    assert score_of(perfect | {"depth_error_mm": -3.0}) == 50.0  # at the goal region's edge
    assert score_of(perfect | {"depth_error_mm": -3.5, "attempted": False}) == 0.0


PILOT = {
    "depth_error_mm": -1.2,
    "overshoot_mm": 0.0,
    "breach": False,
    "time_in_margin_s": 0.0,
    "canal_entered": False,
    "peak_hand_force_n": 16.0,
    "mean_hand_force_n": 12.0,
    "time_to_planned_s": 2.357,
    "feed_cv": 0.4856,
    "reaction_ms": None,
    "wall_contacts": 1,
    "peak_wall_force_n": 20.9,
    "goal_depth_mm": 10.8,
    "attempted": True,
    "hand_force_cv": 0.02,
    "plunge_mm": 0.0,
    "wall_press_s": 0.15,
    "wall_overrun_mm": 1.1,
    "display_lag_ms": None,
    "display_lagged": False,
}
FINAL = {
    "depth_error_mm": -0.7,
    "overshoot_mm": 0.5,
    "breach": True,
    "time_in_margin_s": 0.3,
    "canal_entered": False,
    "peak_hand_force_n": 19.6,
    "mean_hand_force_n": 11.9,
    "time_to_planned_s": 0.374,
    "feed_cv": 0.0663,
    "reaction_ms": 150.0,
    "wall_contacts": 2,
    "peak_wall_force_n": 27.3,
    "goal_depth_mm": 10.8,
    "attempted": True,
    "hand_force_cv": 0.15,
    "plunge_mm": 0.5,
    "wall_press_s": 1.05,  # two contacts: 0.6 s (saturated) and 0.45 s
    "wall_overrun_mm": 2.5,
    "display_lag_ms": 40.0,
    "display_lagged": False,
}


def test_a_sequence_combines_its_drills_as_documented() -> None:
    both = combine_assessments([PILOT, FINAL], drills_planned=2, planned_depth_mm=12.0)
    assert both.to_json() == {
        "depth_error_mm": -0.7,  # the final drill's bed
        "overshoot_mm": 0.5,  # the worst
        "breach": True,  # any
        "time_in_margin_s": 0.3,  # summed
        "canal_entered": False,
        "peak_hand_force_n": 19.6,
        "mean_hand_force_n": 11.95,  # the drills' means averaged
        "time_to_planned_s": 2.731,  # the drills' times to their goals, summed
        "feed_cv": 0.4856,  # the least steady drill
        "reaction_ms": 150.0,  # the slowest known
        "wall_contacts": 2,  # the most of any drill
        "peak_wall_force_n": 27.3,
        "goal_depth_mm": 10.8,  # the final drill's
        "attempted": True,
        "hand_force_cv": 0.15,  # the least steady
        "plunge_mm": 0.5,  # the largest
        "wall_press_s": 1.05,
        "wall_overrun_mm": 2.5,
        "display_lag_ms": 40.0,
        "display_lagged": False,
        # score_of: steady 1 - 0.1 / 0.25 = 0.6, reaction 0.85, plunge 1 / 1.5; wall
        # 1 / (1 + 0.05 / 0.1) / (1 + 0.5 / 2) / 2 = 0.266667; hand 1: skill = 0.705556 *
        # 0.266667 = 0.188148; breached: 45 (1 + skill) / 2 / (1 + 0.5 / 2) = 21.39
        "score": 21.4,
    }
    # the final drill never ran: its bed is not drilled (reached 0 mm), not attempted
    short = combine_assessments([PILOT], drills_planned=3, planned_depth_mm=12.0)
    assert short.depth_error_mm == -12.0 and short.time_to_planned_s is None
    assert not short.attempted and short.score == score_of(short.to_json()) == 0.0
    with pytest.raises(ValueError):
        combine_assessments([PILOT, FINAL], drills_planned=1, planned_depth_mm=12.0)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.booleans(), min_size=1, max_size=4).flatmap(
        lambda flags: st.tuples(*(assessments(breach=b) for b in flags))
    )
)
def test_a_sequence_scores_by_the_same_rule(drills: tuple[dict[str, Any], ...]) -> None:
    parts = [
        d
        | {
            "time_in_margin_s": round(d["time_in_margin_s"], 4),
            "mean_hand_force_n": round(d["mean_hand_force_n"], 3),
            "goal_depth_mm": round(d["goal_depth_mm"], 4),
        }
        for d in drills
    ]
    both = combine_assessments(parts, drills_planned=len(parts), planned_depth_mm=10.0)
    fields = both.to_json()
    assert tuple(fields) == ASSESSMENT_FIELDS
    assert fields["breach"] == any(d["breach"] for d in parts)
    assert fields["overshoot_mm"] == max(d["overshoot_mm"] for d in parts)
    assert fields["wall_contacts"] == max(d["wall_contacts"] for d in parts)
    assert fields["score"] == score_of(fields)
    # a sequence that breached anywhere scores below any attempted one that kept the margin
    assert (fields["score"] <= 45.0) if fields["breach"] else (fields["score"] >= 50.0)
    json.dumps(fields, allow_nan=False)
    if len(parts) == 1:  # one drill: its own assessment (its time rounded as recorded)
        one = dict(parts[0])
        if one["time_to_planned_s"] is not None:
            one["time_to_planned_s"] = round(one["time_to_planned_s"], 4)
        assert fields == one | {"score": score_of(one)}


@pytest.mark.parametrize(("lag_s", "flagged"), [(0.03, False), (0.1, False), (0.435, True)])
def test_the_reaction_is_timed_from_when_the_window_showed_the_breakthrough(
    lag_s: float, flagged: bool
) -> None:
    # The drill crosses the slab's far face at 2 mm/s; the hand lets go 600 ms later; the
    # window shows every 20 ms sample lag_s late. The student reacted to what was on screen.
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=4.0, stop_depth_mm=6.0)
    table = ProfileTable(**{**table.__dict__, "goal_depth_mm": 4.0})

    def run(display: bool) -> Any:
        a = Assessor(_context(max_safe_depth_mm=20.0, goal_depth_mm=6.0), table)
        bt = a.breakthrough_mm
        assert bt is not None
        t_let_go = bt / 2.0 + 0.6
        for i in range(2800):
            t = i / 1000.0
            hand = 9.0 if t < t_let_go - 1e-9 else 0.2
            a.add([_sample(t, 2.0 * t + 0.2, min(2.0 * t, 5.5), 5.0, hand, CUT)])
        if display:
            for k in range(140):
                a.shown(0.02 * k, 0.02 * k + lag_s)
        return a.result()

    plain, seen = run(False), run(True)
    assert plain.reaction_ms == pytest.approx(600.0, abs=1.01)
    assert plain.display_lag_ms is None and not plain.display_lagged
    assert seen.display_lag_ms == pytest.approx(1e3 * lag_s, abs=0.05)
    assert seen.display_lagged is flagged
    # from the first frame at or after the breakthrough (20 ms frames), plus the lag
    assert 600.0 - 1e3 * lag_s - 21.0 <= seen.reaction_ms <= 600.0 - 1e3 * lag_s + 1.0
    if flagged:  # its reaction is not scored: no better, no worse than a session without one
        assert seen.score == score_of(seen.to_json() | {"reaction_ms": None})
    else:
        assert seen.score >= plain.score
