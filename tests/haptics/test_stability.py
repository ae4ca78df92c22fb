"""Stability and passivity of the coupled master: the 11 N/mm coupling and the rigid stop wall
(docs/haptics-stability.md)."""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
import pytest

from ctdrill.haptics import plant
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.plant import ENCODER_M, TRAVEL_MM, ForceController, MasterPlant
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import OperatorKind, SimOperator
from ctdrill.haptics.renderer import (
    PEAK_FORCE_N,
    RELEASE_DAMPING_N_S_PER_MM,
    STOP_WALL_DAMPING_N_S_PER_MM,
    STOP_WALL_N_PER_MM,
    WALL_HOLD_MM,
    Renderer,
)
from ctdrill.haptics.stability import (
    Loop,
    closed_loop_matrix,
    colgate_terms,
    linear_tick,
    release_excursion_bound_mm,
    release_speed_bound_mm_s,
    spectral_radius,
    stiffness_limit_n_per_mm,
)
from ctdrill.haptics.stability_report import (
    coupling_report,
    max_past_stopped_mm,
    report_markdown,
)
from ctdrill.haptics.stability_sim import simulate_push
from ctdrill.model.cutting import DEFAULT_DAMPING_N_S_PER_MM, DEFAULT_STIFFNESS_N_PER_MM
from tests.conftest import ROOT

K = DEFAULT_STIFFNESS_N_PER_MM
B = DEFAULT_DAMPING_N_S_PER_MM
WALL = K + STOP_WALL_N_PER_MM
WALL_B = B + STOP_WALL_DAMPING_N_S_PER_MM


def _wall_limit() -> float:
    return stiffness_limit_n_per_mm(Loop(WALL, WALL_B))


@pytest.mark.parametrize("encoder_m", [ENCODER_M, 1e-15])
def test_the_linear_model_is_the_simulated_tick(
    encoder_m: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Frictionless plant and controller, a hand stepping 20 N onto a surface that holds 40 N
    # (the front stays put: F = k e + b v_e): from rest, 5000 ticks of the linear map follow
    # the emulator's own control tick through the impact's ringing: to float precision with
    # an ideal encoder, within 2 um (0.1 % of the motion) with the 0.1 um one (its rounding
    # enters the velocity estimate and the observers). The matrix is the simulated loop. (The
    # release damper, which acts on the ringing's moves back, is off here: the next test.)
    monkeypatch.setattr(plant, "ENCODER_M", encoder_m)
    tol_mm, tol_n = (2e-3, 0.05) if encoder_m == ENCODER_M else (1e-9, 1e-6)
    emu = DeviceEmulator(nonce_seed=0)
    emu.plant = MasterPlant(coulomb_n=0.0)
    emu.controller = ForceController(dt_s=emu.dt_s, coulomb_n=0.0)
    emu.renderer = Renderer(watchdog_s=math.inf, release_damping_n_s_per_mm=0.0)
    table = ProfileTable.slab(s0_n=40.0, top_mm=0.0, bottom_mm=11.0, stop_depth_mm=10.0)
    emu.renderer.load(table.begin_message(), table.rows())
    assert emu.renderer.arm(0.0, 0.0) is None
    emu._set_operator(SimOperator(int(OperatorKind.PUSH), 20.0))
    state: list[float] = [0.0] * 8
    loop = Loop(K, B)
    error_mm, forces = [], []
    for _ in range(5000):
        state, force = linear_tick(loop, state, 0.0, 20.0)
        emu.control_tick()
        error_mm.append((emu.plant.x_m - state[0]) * 1e3)
        forces.append((force, emu.renderer.force_cmd_n))
    f = np.array(forces)
    assert emu.renderer.front_mm == 0.0 and f[:, 1].max() > 24.0  # it rang (overshoot)
    assert np.max(np.abs(error_mm)) < tol_mm
    assert np.max(np.abs(f[:, 0] - f[:, 1])) < tol_n
    assert state[0] * 1e3 == pytest.approx(20.0 / K, abs=1e-4)  # the spring holds the hand


def test_a_hand_easing_off_is_the_linear_loop_with_the_release_damper(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Frictionless, ideal encoder: a hand holding 20 N on a surface that holds 40 N eases to
    # 5 N. The master moves back all the way (overdamped) with the hand still on it, so the
    # release damper acts on every tick: from the emulator's state at that moment, the linear
    # map with the coupling's damping plus the release damper's follows the emulator's tick
    # (to 1e-9 mm), and without the release damper it does not (the test can tell).
    monkeypatch.setattr(plant, "ENCODER_M", 1e-15)
    emu = DeviceEmulator(nonce_seed=0)
    emu.plant = MasterPlant(coulomb_n=0.0)
    emu.controller = ForceController(dt_s=emu.dt_s, coulomb_n=0.0)
    emu.renderer = Renderer(watchdog_s=math.inf)
    table = ProfileTable.slab(s0_n=40.0, top_mm=0.0, bottom_mm=11.0, stop_depth_mm=10.0)
    emu.renderer.load(table.begin_message(), table.rows())
    assert emu.renderer.arm(0.0, 0.0) is None
    emu._set_operator(SimOperator(int(OperatorKind.PUSH), 20.0))
    for _ in range(5000):  # settled at 20 / 11 mm
        emu.control_tick()
    emu._set_operator(SimOperator(int(OperatorKind.PUSH), 5.0))
    c, p = emu.controller, emu.plant
    start = [p.x_m, p.v_m_s, c._zv, c._yd, c._yr, c.current_a * c.kt, c.velocity_mm_s * 1e-3, 0.0]
    models = {b: list(start) for b in (B + RELEASE_DAMPING_N_S_PER_MM, B)}
    error_mm = {b: 0.0 for b in models}
    for tick in range(3000):
        emu.control_tick()
        if tick > 0:
            assert c.velocity_mm_s < 0.0 and emu.renderer.release_gain() == 1.0
        for b, state in models.items():
            models[b], _ = linear_tick(Loop(K, b), state, 0.0, 5.0)
            error_mm[b] = max(error_mm[b], abs(p.x_m - models[b][0]) * 1e3)
    assert error_mm[B + RELEASE_DAMPING_N_S_PER_MM] < 1e-9
    assert error_mm[B] > 0.1
    assert p.x_m * 1e3 > 5.0 / K  # still easing back, never past the equilibrium


def test_the_matrix_is_the_tick_applied_to_the_basis() -> None:
    loop = Loop(WALL, WALL_B)
    a = closed_loop_matrix(loop)
    assert a.shape == (7, 7)
    s = np.array([1e-4, -2e-3, 5e-5, 0.3, -0.2, 1.5, 1e-3, 0.0])
    nxt, _ = linear_tick(loop, list(s))
    assert np.allclose(a @ s[:7], np.array(nxt[:7]), rtol=1e-12, atol=1e-15)


def _wall_push(factor: float, **kwargs: Any) -> Any:
    """30 N on a wall ``factor`` times the linear limit, the wall's own loop (the release
    damper, which acts on moves back only, off unless given)."""
    kwargs.setdefault("release_damping_n_s_per_mm", 0.0)
    limit = _wall_limit()
    return simulate_push(30.0, stiffness_n_per_mm=factor * limit - STOP_WALL_N_PER_MM, **kwargs)


def test_poles_predict_where_the_simulation_goes_unstable() -> None:
    # Without friction the simulator has exactly the linear model's dynamics: it settles below
    # the predicted limit and its oscillation grows above it, the coupling then giving back
    # energy (D(n) < 0 by joules: the passivity check fails where it should).
    below = _wall_push(0.8, coulomb_n=0)
    above = _wall_push(1.25, coulomb_n=0)
    assert below.settled_range_mm() < 0.005 and not below.clipped
    assert above.settled_range_mm() > 1.0 and above.clipped
    assert below.dissipated_j.min() > -1e-4
    assert above.dissipated_j.min() < -0.1
    # With the master's 1 N Coulomb friction too: settled at 0.8x, ringing at 2x (the wall's
    # damper, not friction, is what keeps the stiff wall stable; at 1.25x the wall, met at the
    # stop depth from the first touch, gets no kick above the friction's band), and by 2x the
    # coupling even returns more energy than it took (E(n) < 0).
    assert _wall_push(0.8).settled_range_mm() == 0.0
    far = _wall_push(2.0)
    assert far.settled_range_mm() > 1.0 and far.energy_in_j.min() < -0.01
    # The release damper, damping every move back, keeps such a wall from ringing up to the
    # peak force, but not from generating energy: the limit stays the wall's.
    damped = _wall_push(2.0, release_damping_n_s_per_mm=RELEASE_DAMPING_N_S_PER_MM)
    assert damped.settled_range_mm() < 0.5 and damped.energy_in_j.min() < -0.01


def test_the_semi_implicit_plant_hid_the_limit() -> None:
    # Semi-implicit Euler conserves a sampled spring's energy (symplectic): its limit is the
    # integrator's omega T = 2, two hundred times the exact (zero-order-hold) plant's.
    symplectic = stiffness_limit_n_per_mm(Loop(WALL, WALL_B, zoh_plant=False))
    assert symplectic > 100.0 * _wall_limit()


@pytest.fixture(scope="module")
def report() -> dict[str, Any]:
    return coupling_report()


def test_the_paper_stiffness_is_stable_with_margin_at_every_operating_point(
    report: dict[str, Any],
) -> None:
    assert report["stiffness_n_per_mm"] == 11.0
    for row in report["poles"]:
        assert row["spectral_radius"] < 1.0, row
        if row["operating point"].startswith(("previous", "at the stop without")):
            continue  # designs compared against, not rendered
        # room for what the model lacks (a resonance, an amplifier's lag): 7.5x at the wall;
        # out of contact (no stiffness) the release damper alone, 8.4x below its own limit
        assert row["margin"] is None or row["margin"] > 7.0, row
        assert row["damping_margin"] > 3.5, row
        assert row["damping_ratio"] > 0.2, row
    released = [r for r in report["poles"] if r["operating point"].startswith("let go")]
    assert [r["damping_n_s_per_mm"] for r in released] == pytest.approx(
        [B + RELEASE_DAMPING_N_S_PER_MM, WALL_B + RELEASE_DAMPING_N_S_PER_MM, 0.4]
    )
    assert released[-1]["stiffness_n_per_mm"] == 0.0 and released[-1]["damping_margin"] > 8.0
    offsets = {(k, wall[0]): mm for k, wall, mm in report["hand_offset_mm"]}
    # the earlier walls (20 N/mm), now met at the stop depth from the first touch: 30 N rests
    # at 30 N / (k + 20) N/mm, within the master's 1 N friction (they held it 2.7 and 8.9 mm
    # past the drill when the wall stood only from the drill's arrival)
    for k in (11.0, 3.2):
        assert offsets[(k, 20.0)] == pytest.approx(30.0 / (k + 20.0), abs=1.0 / (k + 20.0))
    # now the wall holds the hand at 30 N / (11 + 200) N/mm past the stopped drill
    assert offsets[(11.0, STOP_WALL_N_PER_MM)] == pytest.approx(30.0 / WALL, abs=0.01)
    # Without its dampers the wall is unstable (the DOB leaves the master no damping of its
    # own); without the wall's own damper the stiff wall rings (damping ratio 0.05).
    assert spectral_radius(Loop(WALL, 0.0)) > 1.0
    undamped = next(
        r for r in report["poles"] if "without the wall's damper" in r["operating point"]
    )
    assert undamped["damping_ratio"] < 0.1


def test_colgate_terms() -> None:
    terms = colgate_terms(31.0, 0.08, 1e-4)
    assert terms["kt_half_n_s_per_mm"] == pytest.approx(31.0 * 1e-4 / 2.0)
    assert terms["required_b_n_s_per_mm"] == pytest.approx(0.08 + 0.00155)


PUSHES = [0.0, 1.0, 3.9, 4.5, 6.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 78.0]


@pytest.mark.parametrize("step_at_s", [0.0, 0.3])
@pytest.mark.parametrize("push_n", PUSHES)
def test_stable_and_passive_over_operator_forces(push_n: float, step_at_s: float) -> None:
    # A slab S0 = 4 N with the stop 1 mm deep; the hand pushes from the start or steps on at
    # 0.3 s. Bounded, at rest at the end (or cutting at the model's feed, or, at the peak force,
    # pushing through the wall that cannot exceed it), and passive: the coupling never gives
    # back more than it took (E(n) >= 0) and, while no force limit acts, never more than its
    # springs hold (D(n) = E(n) - V(n) >= -1 uJ; the unstable coupling above gives back joules).
    run = simulate_push(push_n, step_at_s=step_at_s, duration_s=1.0)
    assert np.all(np.isfinite(run.master_mm))
    assert TRAVEL_MM[0] <= run.master_mm.min() and run.master_mm.max() <= TRAVEL_MM[1]
    assert run.front_mm.max() <= 1.0
    assert run.force_n.max() <= PEAK_FORCE_N
    assert run.energy_in_j.min() >= 0.0
    if push_n < PEAK_FORCE_N:
        # from 20 N a step from rest 1 mm above the stop meets the wall (rigid from its first
        # touch) fast enough to overshoot the peak on impact, for a few ticks only
        assert not run.clipped or push_n >= 20.0
        if not run.clipped:
            assert run.dissipated_j.min() > -1e-6
        assert run.settled_range_mm() < 1e-3 or 4.0 < push_n < 6.0  # slow cut still going
        if push_n <= 4.0:  # held: the impact's overshoot may nick the surface, then the front
            # relaxes to the spring's equilibrium S0 / k while friction holds the master
            assert run.front_mm[-1] < 0.05
            assert run.front_mm[-1] - run.front_mm[-int(0.2 / 1e-4)] < 1e-4
            assert run.force_n[-1] == pytest.approx(push_n, abs=1.0)
        elif push_n >= 6.0:  # at the stop, the rigid wall holds the hand at the drill
            assert run.front_mm[-1] == 1.0
            assert run.force_n[-1] == pytest.approx(push_n, abs=1.0)
            offset = run.master_mm[-1] - 1.0
            assert offset == pytest.approx(push_n / WALL, abs=1.0 / WALL)
            assert offset < WALL_HOLD_MM
            # the anchor's glide carried the hand back: bounded, at most the force times F/k
            assert 0.0 <= run.glide_j[-1] <= push_n * 1e-3 * push_n / K
            # rigid from its first instant: every tick of the stopped state within the hold,
            # or the peak limit acted (a step from rest arrives too fast for 78 N to stop)
            assert max_past_stopped_mm(run) <= WALL_HOLD_MM or run.clipped
        # the oscillation after the impact decays: the last 0.1 s moves less than the first
        n = int(0.1 / 1e-4)
        i0 = int(step_at_s / 1e-4)
        first = np.ptp(run.master_mm[i0 : i0 + n])
        assert run.settled_range_mm() <= first + 1e-12
    else:  # at the peak force the wall cannot hold: the master drifts on, bounded by travel
        assert run.clipped
        assert run.force_n[-1] == PEAK_FORCE_N
        assert run.master_mm[-1] - 1.0 > WALL_HOLD_MM


def test_the_document_carries_the_computed_numbers(report: dict[str, Any]) -> None:
    text = (ROOT / "docs" / "haptics-stability.md").read_text(encoding="utf-8")
    found = re.search(
        r"<!-- stability-report -->\n(.*?)<!-- /stability-report -->", text, flags=re.S
    )
    assert found is not None, "docs/haptics-stability.md lost its report markers"
    assert found.group(1) == report_markdown(report), (
        "regenerate the tables: python -m ctdrill.haptics.stability_report"
    )


def test_a_hand_that_lets_go_is_not_thrown_back(report: dict[str, Any]) -> None:
    # A hand lets go (0 N at once) while cutting (10-40 N) and at the stop (10-70 N). Before the
    # release damper the springs and the force controller threw the master back and, its
    # friction compensated, it coasted to the end of its travel (21 mm behind the drill). Now
    # its fastest motion back stays under the bound derived from the controller's observers
    # and the damping of the retreat (and is at least 0.4 of it: the bound is not vacuous), it
    # stops within the excursion bound of the surface it left (here: at it), is at rest at the
    # end (below the friction model's 0.1 mm/s) and never meets its travel end; the books never
    # give back more than they took (E(n) >= 0) nor more than the springs held at the release.
    assert len(report["releases"]) == 8
    for row in report["releases"]:
        assert row["before_travel_end"] and row["before_behind_mm"] > 20.0, row
        assert 0.4 * row["speed_bound_mm_s"] <= row["speed_mm_s"] <= row["speed_bound_mm_s"], row
        assert row["behind_mm"] <= row["behind_bound_mm"] < WALL_HOLD_MM, row
        assert row["final_speed_mm_s"] < 0.1 and not row["travel_end"], row
        assert 0.0 <= row["rest_mm"] < 0.01, row  # at the surface it left, not behind it
        assert row["min_energy_in_j"] >= 0.0, row
        assert 0.0 < row["returned_j"] <= row["stored_j"], row
    cutting = [r for r in report["releases"] if r["where"] == "cutting"]
    assert [r["push_n"] for r in cutting] == [10.0, 20.0, 40.0]
    # the coupling's stored energy is what threw the master while cutting: 150 mm/s at 20 N
    # before, a third of it now; the release damper gives back under 5 % of what it held
    assert cutting[1]["before_speed_mm_s"] > 2.5 * cutting[1]["speed_mm_s"]
    assert all(r["returned_j"] < 0.05 * r["stored_j"] for r in cutting)


def test_the_release_bounds() -> None:
    # F (1 / (Mn g) + 1 / B): 20 N, 0.48 N s/mm -> 20 (2 + 2.083) mm/s; braked in 1 / g plus
    # Mn / (Kf B) = 0.5 / (1.2 * 400) s.
    assert release_speed_bound_mm_s(20.0, 0.48) == pytest.approx(20.0 * (2.0 + 1.0 / 0.48))
    assert release_excursion_bound_mm(100.0, 0.4) == pytest.approx(100.0 * (1e-3 + 0.5 / 480.0))
