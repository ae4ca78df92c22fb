"""The stop feels rigid (issue 26): through the whole simulated device, a push up to the peak
force rests within ``WALL_HOLD_MM`` of the stopped drill, or the summary names the device limit
that let it through."""

from __future__ import annotations

import pytest

from ctdrill.app.readout import wall_summary
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.renderer import (
    CONTINUOUS_FORCE_N,
    STOP_WALL_N_PER_MM,
    THERMAL_BUDGET_N2_S,
    WALL_HOLD_MM,
)
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import parse_operator
from ctdrill.haptics.sim import SimulatedDevice
from ctdrill.model.cutting import DEFAULT_STIFFNESS_N_PER_MM

#: A slab (S0 = 4 N) with the stop 2 mm deep.
SLAB = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=2.0)
WALL = DEFAULT_STIFFNESS_N_PER_MM + STOP_WALL_N_PER_MM


def _session(push_n: float, duration_s: float) -> dict[str, object]:
    result = run_session(SimulatedDevice(), SLAB, parse_operator(f"push:{push_n:g}"), duration_s)
    session = result.to_json()
    session.update(wall_summary(session))
    return session


@pytest.mark.parametrize("push_n", [10.0, 30.0, 50.0, 70.0])
def test_a_push_rests_within_half_a_millimetre_of_the_stopped_drill(push_n: float) -> None:
    s = _session(push_n, 1.0)  # within the thermal budget (1.26 s at 70 N)
    assert s["complete"] is True and s["final_state"] == "stopped"
    past = s["hand_past_drill_mm"]
    assert isinstance(past, float) and past <= WALL_HOLD_MM
    # the wall's stiffness, within the master's 1 N friction
    assert past == pytest.approx(push_n / WALL, abs=1.0 / WALL)
    # a step of 70 N from rest 2 mm above the stop reaches the wall at 0.5 m/s: 78 N cannot
    # stop 0.5 kg within 0.5 mm, and the summary says so
    assert s["wall_held"] is (push_n <= 50.0)
    assert s["wall_limits"] == (None if push_n <= 50.0 else ["peak_limit"])


@pytest.mark.parametrize(
    ("s0_n", "stop_mm", "push_n"),
    [(6.0, 4.0, 25.0), (6.0, 4.0, 60.0), (3.0, 6.0, 40.0), (10.0, 2.5, 45.0), (2.0, 3.0, 15.0)],
)
def test_the_wall_is_rigid_from_its_first_instant(
    s0_n: float, stop_mm: float, push_n: float
) -> None:
    # The hand cuts F / 11 N/mm ahead of the drill; the wall stands at the stop depth itself
    # from the hand's first touch, so no sample of the stopped state has the hand more than
    # WALL_HOLD_MM past the stopped drill (a 30 N push used to arrive 2.7 mm past it)
    slab = ProfileTable.slab(s0_n=s0_n, top_mm=0.0, bottom_mm=30.0, stop_depth_mm=stop_mm)
    result = run_session(SimulatedDevice(), slab, parse_operator(f"push:{push_n:g}"), 0.8)
    s = result.to_json()
    s.update(wall_summary(s))
    assert s["final_state"] == "stopped"
    assert s["wall_held"] is True and s["wall_limits"] is None
    assert push_n / WALL - 1.0 / WALL <= s["max_hand_past_drill_mm"] <= WALL_HOLD_MM
    # the drill still reaches the stop depth, on the model's feed (coupling and wall drive it)
    assert s["final_drill_mm"] == pytest.approx(stop_mm, abs=1e-4)


def test_at_the_peak_force_the_summary_names_the_limit_if_the_wall_gives() -> None:
    # The hand pushes as hard as the device can: cutting, the coupling saturates at 78 N and the
    # master outruns the front; the wall cannot push it back
    s = _session(78.0, 0.5)
    assert s["final_state"] == "stopped" and s["wall_held"] is False
    assert s["wall_limits"][0] == "peak_limit"


def test_past_its_thermal_budget_the_summary_names_the_thermal_limit() -> None:
    # 50 N held at the wall spends the I2t budget in (78^2 - 20^2) / (50^2 - 20^2) = 2.7 s;
    # then the device renders its 20 N continuous rating and the hand goes through: named.
    budget_s = THERMAL_BUDGET_N2_S / (50.0**2 - CONTINUOUS_FORCE_N**2)
    s = _session(50.0, budget_s + 1.0)
    assert s["final_state"] == "stopped" and s["wall_held"] is False
    assert s["wall_limits"][0] == "thermal_limit"  # not the impact's brief peak
    assert s["final_force_cmd_n"] == pytest.approx(CONTINUOUS_FORCE_N)


def test_a_session_that_does_not_end_at_the_stop_has_no_wall_account() -> None:
    assert wall_summary(_session(3.0, 0.3)) == {}  # too weak to cut: never at the stop
