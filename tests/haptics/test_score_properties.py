"""The score's properties over synthetic sessions (docs/rehearse.md, "The score"), and a test per
way the old score was gamed, each with other instances than the one the issue quoted.

A synthetic session is ``session.csv``'s rows at 1 kHz read by the assessor as the file would
be: the hand pushes (with seeded noise), the drill advances through a 4 N slab to its deepest
depth, may press on the wall there, then the hand lets go and the session may go on resting,
retracting or waiting.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.haptics.assessment import Assessment, AssessmentContext, Assessor
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.session import csv_cells

RATE_HZ = 1000.0
#: The case: a 4 N slab from 0.5 mm, the canal's surface 12.8 mm down (clearance 12.8 - x),
#: the max safe depth 10.8 mm; the plan asks 12.6 mm, so the goal is the max safe depth.
SAFE_MM, PLANNED_MM, CANAL_MM = 10.8, 12.6, 12.8


def _context(*, goal_mm: float = SAFE_MM, safe_mm: float = SAFE_MM) -> AssessmentContext:
    depth = np.linspace(0.0, 40.0, 801)
    return AssessmentContext(
        planned_depth_mm=PLANNED_MM,
        max_safe_depth_mm=safe_mm,
        goal_depth_mm=goal_mm,
        clearance_depth_mm=depth,
        clearance_mm=CANAL_MM - depth,
    )


def _table(stop_mm: float, goal_mm: float | None = None) -> ProfileTable:
    slab = ProfileTable.slab(s0_n=4.0, top_mm=0.5, bottom_mm=38.0, stop_depth_mm=stop_mm)
    return replace(slab, goal_depth_mm=goal_mm)


@dataclass(frozen=True)
class Script:
    """A synthetic session: push ``push_n`` (noise ``noise_n``, seeded) while the drill
    advances at ``feed_mm_s`` to ``deepest_mm``; at the wall (``deepest_mm`` = the stop) press
    ``press_s`` with the handle ``overrun_mm`` past the drill; then let go and, after, a tail
    of ``tail`` (``rest``, ``retract``, ``wait``) for ``tail_s``; or never let go: ``hold``
    keeps pressing on the wall with the constant push ``push_n`` for ``tail_s``, ``lean`` leans
    on it ever harder (10 N and 1 mm more a second)."""

    deepest_mm: float
    push_n: float = 12.0
    noise_n: float = 0.0
    feed_mm_s: float = 4.0
    press_s: float = 0.0
    overrun_mm: float = 0.1
    retract_to_mm: float | None = None
    tail: str = "rest"
    tail_s: float = 0.0
    seed: int = 0


def _rows(s: Script, stop_mm: float) -> list[tuple[float, float, float, float, str, float]]:
    rng = random.Random(s.seed)
    rows: list[tuple[float, float, float, float, str, float]] = []
    t = 0.0
    drill = 0.0
    noise = 0.0
    dt = 1.0 / RATE_HZ
    i = 0

    def hand() -> float:
        nonlocal noise
        if s.noise_n > 0.0 and i % 10 == 0:  # a new value every 10 ms, as the human hand's
            noise = rng.gauss(0.0, s.noise_n)
        return s.push_n + noise

    while drill < s.deepest_mm - 1e-12:
        drill = min(drill + s.feed_mm_s * dt, s.deepest_mm)
        rows.append((t, drill + 0.05, drill, 4.0, "cutting", hand()))
        t += dt
        i += 1
    at_wall = s.deepest_mm >= stop_mm - 1e-9
    for _ in range(round(s.press_s * RATE_HZ)):
        state = "stopped" if at_wall else "cutting"
        rows.append((t, drill + s.overrun_mm, drill, s.push_n, state, hand()))
        t += dt
        i += 1
    state = "stopped" if at_wall else "cutting"
    if s.retract_to_mm is not None:  # pull the drill back out of the margin zone
        while drill > s.retract_to_mm:
            drill = max(drill - 5.0 * dt, s.retract_to_mm)
            rows.append((t, drill, drill, 0.0, "cutting", -2.0))
            t += dt
        state = "cutting"
    for k in range(round(s.tail_s * RATE_HZ)):
        if s.tail == "hold":  # the same push, the handle where the press left it
            rows.append((t, drill + s.overrun_mm, drill, s.push_n, state, s.push_n))
        elif s.tail == "lean":  # never letting go, leaning harder and deeper (a stiff hand)
            lean = k / RATE_HZ
            rows.append(
                (t, drill + s.overrun_mm + lean, drill, s.push_n, state, s.push_n + 10.0 * lean)
            )
        elif s.tail == "retract":
            drill = max(drill - 5.0 * dt, 0.0)
            rows.append((t, drill, drill, 0.0, "cutting", -2.0))
        elif s.tail == "wait":
            rows.append((t, drill - 0.3, drill, 0.0, state, 0.3 * (k % 2)))
        else:
            rows.append((t, drill, drill, 0.0, state, 0.0))
        t += dt
    return rows


def assess(
    s: Script, *, stop_mm: float = 30.0, goal_mm: float = SAFE_MM, safe_mm: float = SAFE_MM
) -> Assessment:
    """The assessment of ``s`` as its ``session.csv`` would give it."""
    table = _table(stop_mm, goal_mm if stop_mm > goal_mm + 1e-9 else None)
    a = Assessor(_context(goal_mm=goal_mm, safe_mm=safe_mm), table)
    for row in _rows(s, stop_mm):
        a.add_cells(csv_cells(row))
    return a.result()


pushes = st.floats(4.5, 19.0)
noises = st.floats(0.0, 0.3)


# ------------------------------------------------------------------------------ properties
@settings(max_examples=25, deadline=None)
@given(
    st.floats(11.0, 16.0),
    st.floats(0.1, 6.0),
    pushes,
    noises,
    st.integers(0, 10_000),
)
def test_deeper_overshoot_never_scores_higher(
    deepest: float, more: float, push: float, noise: float, seed: int
) -> None:
    # exam mode (the stop 30 mm down): the same hand, the drill let go deeper
    shallow = assess(Script(deepest, push, noise, seed=seed))
    deep = assess(Script(deepest + more, push, noise, seed=seed))
    assert shallow.breach and deep.breach and deep.overshoot_mm > shallow.overshoot_mm
    assert deep.score <= shallow.score


@settings(max_examples=25, deadline=None)
@given(
    st.floats(2.0, 16.0),
    pushes,
    noises,
    st.sampled_from(["rest", "retract", "wait"]),
    st.floats(0.01, 3.0),
    st.booleans(),
)
def test_nothing_after_the_last_cutting_event_changes_the_assessment(
    deepest: float, push: float, noise: float, tail: str, tail_s: float, guarded: bool
) -> None:
    stop = SAFE_MM if guarded else 30.0
    deepest = min(deepest, stop)
    base = Script(deepest, push, noise, press_s=0.2 if guarded else 0.0)
    short = assess(base, stop_mm=stop)
    longer = assess(replace(base, tail=tail, tail_s=tail_s), stop_mm=stop)
    assert longer == short  # every field, the score with them: no dependence on length


@settings(max_examples=25, deadline=None)
@given(st.floats(0.0, 7.7), pushes, st.floats(10.9, 16.0), pushes)
def test_a_session_short_of_the_goal_region_is_not_attempted_and_ranks_below(
    deepest: float, push: float, breach_mm: float, push2: float
) -> None:
    idle = assess(Script(deepest, push) if deepest > 0 else Script(0.0, 0.0))
    assert not idle.attempted and idle.score == 0.0 and not idle.breach
    # below every attempted session, a breach into the canal included
    worst = assess(Script(breach_mm, push2, feed_mm_s=8.0))
    assert worst.attempted and worst.score >= idle.score
    near = assess(Script(7.9, push))  # 2.9 mm short: attempted, scored
    assert near.attempted and near.score >= 50.0


@settings(max_examples=20, deadline=None)
@given(st.floats(3.0, 25.0), st.floats(0.0, 5.0), pushes, st.floats(0.0, 0.45))
def test_a_perfect_guarded_session_scores_100_on_every_case(
    planned: float, safe_beyond: float, push: float, press_s: float
) -> None:
    # goal = min(planned drilled depth, max safe depth): the guard stops the drill there
    safe = planned - 2.0 + safe_beyond
    goal = min(planned, safe)
    a = assess(Script(goal, push, press_s=press_s), stop_mm=goal, goal_mm=goal, safe_mm=safe)
    assert a.goal_depth_mm == pytest.approx(goal, abs=1e-4) and a.attempted
    assert a.score == 100.0


# ------------------------------------------------------------- the gaming cases, each class
@pytest.mark.parametrize(("shallow", "deep"), [(11.5, 13.0), (12.0, 16.0), (11.0, 11.6)])
def test_a_deeper_breach_then_a_retraction_scores_below_a_shallower_breach(
    shallow: float, deep: float
) -> None:
    # the instance: 21.2 for the deeper breach pulled back, 13.4 for the shallower one
    # left in the margin zone (time in the margin counted to the session's end)
    left_in = assess(Script(shallow, tail="rest", tail_s=5.0))
    pulled_back = assess(Script(deep, retract_to_mm=SAFE_MM - 1.0, tail_s=5.0))
    assert pulled_back.overshoot_mm > left_in.overshoot_mm
    assert pulled_back.score < left_in.score


@pytest.mark.parametrize("deepest", [9.0, 10.8, 12.5])
@pytest.mark.parametrize(("short_s", "long_s"), [(0.5, 6.0), (2.0, 30.0)])
def test_the_same_actions_score_the_same_in_a_longer_session(
    deepest: float, short_s: float, long_s: float
) -> None:
    # the instance: 25.4 in a 4 s session, 13.4 in a 10 s one
    stop = SAFE_MM if deepest == SAFE_MM else 30.0
    press = 0.3 if stop == SAFE_MM else 0.0
    a = assess(Script(deepest, press_s=press, tail_s=short_s), stop_mm=stop)
    b = assess(Script(deepest, press_s=press, tail_s=long_s), stop_mm=stop)
    assert a == b


@pytest.mark.parametrize("drilled", [0.0, 0.2, 3.0, 7.0])
def test_not_drilling_scores_below_every_breach(drilled: float) -> None:
    # the instance: not drilling at all scored 50, above every breach
    idle = assess(Script(drilled) if drilled else Script(0.0, 0.0, tail_s=3.0))
    assert not idle.attempted and idle.score == 0.0
    for deep, push in ((11.0, 12.0), (16.0, 19.0), (20.0, 30.0)):
        breach = assess(Script(deep, push, feed_mm_s=9.0))
        assert breach.breach and breach.score > idle.score


@pytest.mark.parametrize("push", [8.0, 12.0, 16.0])
@pytest.mark.parametrize("noise", [1.5, 3.0, 5.0])
def test_a_noisy_hand_never_scores_above_a_steady_one(push: float, noise: float) -> None:
    # the instance: 3 N of noise scored above a steady 12 N hand (the feed's variation
    # was measured, and the bone's layers dominate it)
    steady = assess(Script(SAFE_MM, push, press_s=0.2), stop_mm=SAFE_MM)
    noisy = [
        assess(Script(SAFE_MM, push, noise, press_s=0.2, seed=k), stop_mm=SAFE_MM) for k in range(3)
    ]
    assert steady.score == 100.0
    for a in noisy:
        assert a.hand_force_cv is not None and steady.hand_force_cv is not None
        assert a.hand_force_cv > steady.hand_force_cv and a.score <= steady.score
        if noise / push >= 0.25:  # 3 N on 12 N and more: it costs
            assert a.score < steady.score


@pytest.mark.parametrize(("push", "overrun"), [(30.0, 49.0), (26.0, 5.0), (40.0, 20.0)])
def test_pushing_through_the_wall_costs_points(push: float, overrun: float) -> None:
    # the instance: 30 N through the thermal limit, 49 mm past the wall, lost 0.8
    careful = assess(Script(SAFE_MM, 12.0, press_s=0.3), stop_mm=SAFE_MM)
    brute = assess(Script(SAFE_MM, push, press_s=3.0, overrun_mm=overrun), stop_mm=SAFE_MM)
    assert careful.score == 100.0
    # kept the margin (50 and up), but (almost) every skill point lost
    assert brute.score < careful.score - 20.0
    assert brute.wall_overrun_mm == pytest.approx(overrun, abs=1e-4)


def test_pressing_on_the_wall_longer_than_a_reaction_costs_and_saturates() -> None:
    scores = [
        assess(Script(SAFE_MM, 12.0, press_s=p), stop_mm=SAFE_MM).score
        for p in (0.2, 0.45, 0.55, 0.7, 1.0, 3.0)
    ]
    # free within the grace (a reaction to the wall), dearer up to grace + saturation, then
    # the same: a hand still on the wall has shown it will not let go, the rest is waiting
    assert scores[0] == scores[1] == 100.0 and scores[1] > scores[2] > scores[3]
    assert scores[3] == scores[4] == scores[5] < 90.0


@settings(max_examples=25, deadline=None)
@given(
    pushes,
    st.floats(0.65, 2.0),
    st.floats(0.01, 3.0),  # the handle beyond the drill: a contact with the wall
    st.floats(0.01, 8.0),
    st.sampled_from(["rest", "retract", "wait", "hold", "lean"]),
)
def test_appending_any_tail_never_changes_the_score(
    push: float, press_s: float, overrun: float, tail_s: float, tail: str
) -> None:
    # a guarded session that met the wall and pressed past the grace (or let go, for the tails
    # after a release): whatever follows, resting, retracting, waiting or holding the same push
    # against the wall for any time, or leaning on it ever harder (the pressing has
    # saturated: the hand has shown it will not let go), changes nothing the score reads
    base = Script(SAFE_MM, push, press_s=press_s, overrun_mm=overrun)
    short = assess(base, stop_mm=SAFE_MM)
    longer = assess(replace(base, tail=tail, tail_s=tail_s), stop_mm=SAFE_MM)
    assert longer.score == short.score
    if tail == "lean":  # the mean push (reported, not scored) is the whole session's
        longer = replace(longer, mean_hand_force_n=short.mean_hand_force_n)
    assert longer == short
