"""Hands: the human operator's grammar, the breakthrough on a table, reactions in a session."""

from __future__ import annotations

import statistics

import numpy as np
import pytest

from ctdrill.haptics.assessment import AssessmentContext, Assessor
from ctdrill.haptics.hands import (
    RETRACT_MM_S,
    HumanHand,
    LiveHand,
    breakthrough_depths_mm,
    decisive_breakthrough_mm,
    first_breakthrough_mm,
)
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import OperatorKind
from ctdrill.haptics.run import SessionResult, run_session
from ctdrill.haptics.session import HumanSpec, SessionInputError, parse_operator
from ctdrill.haptics.sim import SimulatedDevice

STEP = 0.05


def _table(s0: np.ndarray, stop_mm: float, goal_mm: float | None = None) -> ProfileTable:
    zeros = np.zeros_like(s0)
    return ProfileTable(STEP, s0, zeros, zeros, 0.25, np.array([30.0, 60.0]), stop_mm, goal_mm)


def test_human_grammar() -> None:
    op = parse_operator("human:force=12,react_ms=150")
    assert op.kind == "human" and op.value == 12.0
    assert op.human == HumanSpec(12.0, 150.0, 0.0, 0)
    assert parse_operator("human:seed=4,noise_n=1.5,react_ms=0,force=0.5").human == HumanSpec(
        0.5, 0.0, 1.5, 4
    )
    for spec, field in [
        ("human:react_ms=150", "force"),
        ("human:force=12", "react_ms"),
        ("human:force=12,react_ms=-1", "react_ms"),
        ("human:force=0,react_ms=10", "force"),
        ("human:force=79,react_ms=10", "force"),
        ("human:force=nan,react_ms=10", "force"),
        ("human:force=12,react_ms=10,noise_n=-2", "noise_n"),
        ("human:force=12,react_ms=10,seed=-3", "seed"),
        ("human:force=12,react_ms=10,seed=1.5", "seed"),
        ("human:force=12,react_ms=10,speed=3", "speed"),
        ("human:force=12,force=13,react_ms=10", "force"),
        ("human:force=12;react_ms=10", "force=12;react_ms=10"),
    ]:
        with pytest.raises(SessionInputError) as err:
            parse_operator(spec)
        message = str(err.value)
        assert message.startswith(f"--operator {spec!r}") and field in message
        assert "\n" not in message


def test_breakthrough_of_a_slab_is_its_far_face() -> None:
    depth = np.arange(0, 401) * STEP
    slab = np.where((depth >= 1.0) & (depth <= 6.0), 4.0, 0.0)
    assert breakthrough_depths_mm(_table(slab, 19.0)) == pytest.approx((6.05,))
    assert first_breakthrough_mm(_table(slab, 5.0)) is None  # the stop comes first
    weak = np.where((depth >= 1.0) & (depth <= 6.0), 0.9, 0.0)  # below a hand's feel (1 N)
    assert breakthrough_depths_mm(_table(weak, 19.0)) == ()


def test_breakthrough_is_a_fall_to_half_within_half_a_millimetre() -> None:
    depth = np.arange(0, 401) * STEP
    # Two layers: 8 N then 4.6 N (the demo's cortical and trabecular bone): not a breakthrough;
    # 8 N then 3.9 N is one, at the first row of the softer layer.
    for soft, expected in ((4.6, ()), (3.9, (4.0,))):
        s0 = np.where(depth < 2.0, 0.0, np.where(depth < 4.0, 8.0, soft))
        assert breakthrough_depths_mm(_table(s0, 19.0)) == pytest.approx(expected)
    # A ramp from 8 N at 2 mm down to 0 at 4 mm: S0(x) = 8 - 4 (x - 2); the peak over the last
    # 0.5 mm is S0(x - 0.5) = S0(x) + 2, so S0 < half of it once S0 < 2 N: x > 3.5 mm.
    ramp = np.clip(8.0 - 4.0 * (depth - 2.0), 0.0, 8.0) * (depth >= 2.0)
    assert breakthrough_depths_mm(_table(ramp, 19.0)) == pytest.approx((3.55,))


def test_noise_is_seeded_gaussian_at_100_hz() -> None:
    table = _table(np.zeros(10), 0.4)
    a = HumanHand(HumanSpec(10.0, 100.0, 2.0, 7), table)
    b = HumanHand(HumanSpec(10.0, 100.0, 2.0, 7), table)
    c = HumanHand(HumanSpec(10.0, 100.0, 2.0, 8), table)
    times = [i * 0.01 + 0.004 for i in range(2000)]
    fa = [a.command(t)[1] for t in times]
    assert fa == [b.command(t)[1] for t in times]
    assert fa != [c.command(t)[1] for t in times]
    assert a.command(times[-1] + 0.005)[1] == fa[-1]  # held within its 10 ms
    # 2000 draws: the sample mean within 4 standard errors, the spread within 10 %
    assert statistics.fmean(fa) == pytest.approx(10.0, abs=4 * 2.0 / np.sqrt(2000))
    assert statistics.pstdev(fa) == pytest.approx(2.0, rel=0.1)
    quiet = HumanHand(HumanSpec(10.0, 100.0), table)
    assert {quiet.command(t)[1] for t in times} == {10.0}


def _exam_session(
    react_ms: float, *, stop_mm: float = 15.0
) -> tuple[Assessor, HumanHand, SessionResult]:
    """8 N through 4 N bone from 0.5 to 3 mm, a 0.6 mm void (a canal: the landmark, 3 mm
    down), then bone again."""
    depth = np.arange(0, 401) * STEP
    bone = (depth >= 0.5) & ((depth <= 3.0) | (depth >= 3.6))
    table = _table(np.where(bone, 4.0, 0.0), stop_mm, goal_mm=1.0)
    context = AssessmentContext(
        planned_depth_mm=1.0,
        max_safe_depth_mm=1.0,
        goal_depth_mm=1.0,
        clearance_depth_mm=depth,
        clearance_mm=3.0 - depth,
    )
    assessor = Assessor(context, table)
    hand = HumanHand(HumanSpec(8.0, react_ms), table)
    result = run_session(
        SimulatedDevice(),
        table,
        parse_operator(f"human:force=8,react_ms={react_ms:g}"),
        1.2,
        on_samples=assessor.add,
        hand=hand,
    )
    return assessor, hand, result


def test_a_later_reaction_goes_deeper() -> None:
    runs = {ms: _exam_session(ms) for ms in (20.0, 150.0, 300.0)}
    deepest = [a.deepest_mm for a, _, _ in runs.values()]
    assert deepest == sorted(deepest) and deepest[0] + 0.2 < deepest[-1]
    for ms, (assessor, hand, result) in runs.items():
        # let go in the bone below the void: the handle rests on the hole's bottom, at most
        # a few micrometres past the drill (the device's release damper), not thrown back
        assert result.final_master_mm is not None and result.final_drill_mm is not None
        assert 0.0 <= result.final_master_mm - assessor.deepest_mm < 0.01
        assert result.faults == []
        assert hand.cue is not None and hand.cue[0] == "breakthrough"
        assert hand.release_s == pytest.approx(hand.cue[1] + ms / 1000.0)
        a = assessor.result()
        assert a.breach and a.overshoot_mm == pytest.approx(assessor.deepest_mm - 1.0, abs=1e-4)
        # the hand is read as let go within one 10 ms block (plus the observer's lag)
        assert a.reaction_ms is not None and ms <= a.reaction_ms <= ms + 13.0
        assert a.canal_entered


def test_the_hand_lets_go_at_the_wall() -> None:
    # the guard: the stop at the max safe depth
    assessor, hand, result = _exam_session(80.0, stop_mm=1.0)
    # let go at the wall: the handle rests at the stopped drill, nothing flagged (it used to be
    # thrown back and coast to its travel end: travel_limit)
    assert result.faults == [] and result.final_state == "stopped"
    assert result.final_master_mm == pytest.approx(1.0, abs=0.01)
    assert hand.cue is not None and hand.cue[0] == "wall"
    assert hand.command(hand.cue[1] + 0.079) == (int(OperatorKind.PUSH), 8.0)
    assert hand.command(hand.cue[1] + 0.080) == (int(OperatorKind.PUSH), 0.0)
    a = assessor.result()
    assert not a.breach and a.overshoot_mm == 0.0 and a.time_in_margin_s == 0.0
    assert a.reaction_ms is None and a.wall_contacts >= 1 and not a.canal_entered
    assert a.peak_wall_force_n > 0.0 and assessor.deepest_mm == pytest.approx(1.0, abs=1e-3)
    assert a.time_to_planned_s is not None and a.feed_cv is None  # under two 0.1 s windows
    # 8 N on 4 N bone: the model's feed (8 / 4 - 1) / 0.25 = 4 mm/s, 0.5 mm of bone to the
    # stop in 0.125 s (plus the start: the master's travel to the surface and the spring)
    assert 0.125 < a.time_to_planned_s < 0.2


def test_live_hand_follows_its_push_and_retracts_out_of_the_hole() -> None:
    push = [6.0]
    retract = [False]
    hand = LiveHand(lambda: push[0], lambda: retract[0])
    assert hand.command(0.0) == (int(OperatorKind.PUSH), 6.0)
    push[0] = 200.0
    assert hand.command(0.0) == (int(OperatorKind.PUSH), 78.0)
    push[0] = float("nan")
    assert hand.command(0.0) == (int(OperatorKind.PUSH), 0.0)
    retract[0] = True
    hand.master_mm = 3.0
    assert hand.command(0.0) == (int(OperatorKind.FEED), -RETRACT_MM_S)
    hand.master_mm = 0.0
    assert hand.command(0.0) == (int(OperatorKind.PUSH), 0.0)


def _d4_table(stop_mm: float, goal_mm: float | None = None) -> ProfileTable:
    """The D4 phantom's cutting force along its plan (``make_mandible_phantom(misch="D4",
    spacing_mm=0.5)``, bone-illustrative: measured 0.8 N in the gum, 7.0 N in the crestal
    cortex, 1.7 N in the trabecular bone below): the crest's step into soft bone breaks
    through by the table's rule (at 1.9 mm on the phantom)."""
    depth = np.arange(0, 401) * STEP
    s0 = np.where(depth < 0.5, 0.8, np.where(depth < 1.8, 7.0, 1.74))
    return _table(s0, stop_mm, goal_mm)


@pytest.mark.parametrize("goal_mm", [6.0, 10.8, 14.0])
def test_the_crestal_cortex_is_not_the_breakthrough_that_matters(goal_mm: float) -> None:
    table = _d4_table(goal_mm)
    first = first_breakthrough_mm(table)
    assert first is not None and 1.8 <= first <= 1.85  # the crest's exit, by the table's rule
    assert decisive_breakthrough_mm(table) is None  # a layer the osteotomy drills through
    # in an exam (the table runs past the goal) the canal's roof beyond it is the one
    depth = np.arange(0, 401) * STEP
    s0 = np.where(depth < 0.5, 0.8, np.where(depth < 1.8, 7.0, 1.74))
    s0 = np.where((depth >= goal_mm + 1.0) & (depth < goal_mm + 3.0), 0.0, s0)
    exam = _table(s0, goal_mm + 6.0, goal_mm)
    found = decisive_breakthrough_mm(exam)
    assert found is not None and goal_mm + 1.0 <= found <= goal_mm + 1.05


def test_a_careful_d4_session_is_scripted_without_a_late_reaction() -> None:
    # 9 N through the D4 crest, then on through the soft bone to the wall at the goal: the
    # scripted hand lets go at the wall, not 150 ms after the crest (which would stop it
    # 8 mm short), and no reaction is charged
    goal = 10.8
    table = _d4_table(goal)
    depth = np.arange(0, 401) * STEP
    context = AssessmentContext(
        planned_depth_mm=12.6,
        max_safe_depth_mm=goal,
        goal_depth_mm=goal,
        clearance_depth_mm=depth,
        clearance_mm=12.8 - depth,
    )
    assessor = Assessor(context, table)
    hand = HumanHand(HumanSpec(9.0, 150.0), table)
    result = run_session(
        SimulatedDevice(),
        table,
        parse_operator("human:force=9,react_ms=150"),
        4.0,
        on_samples=assessor.add,
        hand=hand,
    )
    assert result.faults == [] and hand.cue is not None and hand.cue[0] == "wall"
    a = assessor.result()
    assert a.reaction_ms is None and a.plunge_mm == 0.0 and not a.breach
    assert a.depth_error_mm == pytest.approx(0.0, abs=1e-3) and a.score == 100.0
