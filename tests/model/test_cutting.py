"""The interactive cutting law (DESIGN 1.7-1.8) with exact expected values."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ctdrill.model.cutting import (
    DEFAULT_DAMPING_N_S_PER_MM,
    DEFAULT_STIFFNESS_N_PER_MM,
    advance_front_mm,
    cut_step,
    equilibrium_penetration_mm,
    resistance_n,
    steady_feed_mm_s,
    vibration_n,
)

K = DEFAULT_STIFFNESS_N_PER_MM
DT = 1e-4


def test_default_gains_are_the_paper_master_stiffness_and_velocity_gain() -> None:
    assert K == 11.0  # the paper's master, Table 1 (docs/haptics-stability.md)
    assert abs(DEFAULT_DAMPING_N_S_PER_MM - 0.08) < 1e-12  # 0.5 kg * 160 / s = 80 N s/m


def test_no_force_and_no_cut_inside_the_hole() -> None:
    assert advance_front_mm(5.0, 4.0, 3.0, 0.25, DT) == 5.0
    assert advance_front_mm(5.0, 5.0, 3.0, 0.25, DT) == 5.0
    assert cut_step(5.0, 4.0, 3.0, 0.25, DT) == (5.0, 0.0)
    assert cut_step(5.0, 5.0, 3.0, 0.25, DT) == (5.0, 0.0)
    assert resistance_n(0.0, 10.0, 0.0, 1.0) == 0.0


def test_holds_up_to_s0_at_rest() -> None:
    s0 = 4.0
    e_star = equilibrium_penetration_mm(s0)
    assert e_star == pytest.approx(4.0 / 11.0)
    # Pushing with 3.9 N (< S0): the front does not move, the hand feels exactly 3.9 N.
    master = 2.0 + 3.9 / K
    for _ in range(1000):
        assert advance_front_mm(2.0, master, s0, 0.25, DT) == 2.0
    front, coupling = cut_step(2.0, master, s0, 0.25, DT)
    assert front == 2.0 and coupling == pytest.approx(3.9)
    assert resistance_n(coupling, 0.0, 0.0, 0.0) == pytest.approx(3.9)
    # At exactly S0 it still holds.
    assert advance_front_mm(2.0, 2.0 + e_star, s0, 0.25, DT) == 2.0


@pytest.mark.parametrize(("force_n", "s0_n", "ke"), [(6.0, 4.0, 0.25), (20.0, 2.0, 0.25)])
def test_constant_hand_force_gives_the_steady_feed(force_n: float, s0_n: float, ke: float) -> None:
    # A constant hand force F keeps the penetration at F/k: each step advances v dt exactly,
    # v = (F/S0 - 1)/Ke (6 N on 4 N: 2 mm/s; 20 N on 2 N: 36 mm/s).
    expected = (force_n / s0_n - 1.0) / ke
    assert steady_feed_mm_s(force_n, s0_n, ke) == pytest.approx(expected)
    front = 1.0
    for _ in range(100):
        new = advance_front_mm(front, front + force_n / K, s0_n, ke, DT)
        assert (new - front) / DT == pytest.approx(expected, rel=1e-9)
        # ... and the force the front sustained is the hand's.
        assert cut_step(front, front + force_n / K, s0_n, ke, DT) == (new, pytest.approx(force_n))
        front = new
    assert front == pytest.approx(1.0 + 100 * DT * expected, rel=1e-9)


def test_steady_cut_at_constant_master_feed_reaches_a0_of_that_feed() -> None:
    # Master driven at 1 mm/s into S0 = 4 N, Ke = 0.25: the force settles at S0 (1 + Ke v)
    # = 5 N, the front moving at the master's feed. The damping term vanishes in steady state.
    s0, ke, v = 4.0, 0.25, 1.0
    front, master = 0.0, 0.0
    force = 0.0
    for _ in range(60_000):  # 6 s; contact builds for 1.25 s, then time constant S0 Ke/k 0.31 s
        master += v * DT
        new, coupling = cut_step(front, master, s0, ke, DT)
        force = resistance_n(coupling, v, (new - front) / DT, 0.0)
        front = new
    assert force == pytest.approx(s0 * (1.0 + ke * v), rel=1e-7)


def test_ke_zero_is_rigid_plastic_and_s0_zero_is_air() -> None:
    # Ke = 0: the front jumps so that the coupling force is exactly S0: k (3 - front) = 3.2.
    new, coupling = cut_step(0.0, 3.0, 3.2, 0.0, DT)
    assert new == pytest.approx(3.0 - 3.2 / 11.0)
    assert coupling == pytest.approx(3.2)
    # S0 = 0 (or negative): nothing to cut, the front follows the master, no force.
    assert advance_front_mm(0.0, 3.0, 0.0, 0.25, DT) == 3.0
    assert advance_front_mm(0.0, 3.0, -1.0, 0.25, DT) == 3.0
    assert steady_feed_mm_s(5.0, 0.0, 0.25) == math.inf
    assert steady_feed_mm_s(5.0, 4.0, 0.0) == math.inf
    assert steady_feed_mm_s(3.0, 4.0, 0.25) == 0.0


def test_front_never_passes_the_limit() -> None:
    assert advance_front_mm(9.9, 30.0, 1.0, 0.0, DT, limit_mm=10.0) == 10.0
    # free advance at v = (k e / S0 - 1) / Ke = (11 * 20.1 - 1) / 0.25 = 880.4 mm/s
    assert advance_front_mm(9.9, 30.0, 1.0, 0.25, DT) == pytest.approx(9.9 + 880.4 * DT)
    assert advance_front_mm(10.0, 30.0, 0.0, 0.25, DT, limit_mm=10.0) == 10.0


def test_resistance_adds_damping_and_vibration_and_never_pulls() -> None:
    # coupling + b (vm - vf) + vib = 1.6 + 0.08 * (10 - 2) + 0.3
    assert resistance_n(1.6, 10.0, 2.0, 0.3) == pytest.approx(1.6 + 0.64 + 0.3)
    # Retracting fast while still beyond the front: the total is clipped at 0, never negative.
    assert resistance_n(0.032, -1000.0, 0.0, 0.0) == 0.0
    # At the limit the spring keeps compressing: the force is k e after the step.
    assert cut_step(10.0, 12.0, 1.0, 0.25, DT, limit_mm=10.0) == (10.0, pytest.approx(22.0))


def test_vibration_is_eq19() -> None:
    assert vibration_n(1.0, 0.5, 30.0, 60.0, 0.0) == 0.0
    # t = 1/240 s: sin(pi/4) and sin(pi/2).
    assert vibration_n(1.0, 0.5, 30.0, 60.0, 1.0 / 240.0) == pytest.approx(
        math.sin(math.pi / 4) + 0.5
    )


finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False)


@given(
    front=finite,
    master=finite,
    s0=st.floats(min_value=-1.0, max_value=100.0),
    ke=st.floats(min_value=0.0, max_value=10.0),
    limit=finite,
)
def test_front_is_monotone_bounded_and_finite(
    front: float, master: float, s0: float, ke: float, limit: float
) -> None:
    new = advance_front_mm(front, master, s0, ke, DT, limit_mm=limit)
    assert math.isfinite(new)
    assert new >= front
    assert new <= max(front, min(master, limit)) + 1e-12
    new2, coupling = cut_step(front, master, s0, ke, DT, limit_mm=limit)
    assert new2 == new
    assert math.isfinite(coupling) and coupling >= 0.0
    # The coupling force never exceeds what the spring held at the start of the tick.
    assert coupling <= K * max(master - front, 0.0) * (1 + 1e-12) + 1e-12
