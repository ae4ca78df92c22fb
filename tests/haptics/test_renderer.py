"""The device renderer alone, driven by prescribed master trajectories (exact answers)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState, Fault, NakReason
from ctdrill.haptics.renderer import (
    RELEASE_DAMPING_N_S_PER_MM,
    RELEASE_HOLD_TICKS,
    RELEASE_MAX_N,
    STOP_GLIDE_MM_S,
    STOP_WALL_N_PER_MM,
    Renderer,
)
from ctdrill.model.profile import Profile, force_n

DT = 1e-4


def armed(table: ProfileTable, **kwargs: float) -> Renderer:
    r = Renderer(**kwargs)  # type: ignore[arg-type]
    r.load(table.begin_message(), table.rows())
    assert r.arm(0.0, 0.0) is None
    return r


def test_rendered_force_on_a_slab_matches_the_model_at_steady_feed() -> None:
    # Slab from 0 to 40 mm, S0 = 4 N, S1 = 0.25 N, S2 = 0.125 N (float32-exact), Ke 0.25.
    # The master advances at 1 mm/s; once the front moves with it (time constant
    # S0 Ke / k = 0.31 s), the rendered force is the model's F(x, v, t) at the front.
    table = ProfileTable.slab(
        s0_n=4.0, s1_n=0.25, s2_n=0.125, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=30.0
    )
    depth = table.depth_mm
    profile = Profile(
        depth_mm=depth,
        s0_n=table.s0_n.astype(float),
        sk_n=np.vstack([table.s1_n, table.s2_n]).astype(float),
        freqs_hz=np.array([30.0, 60.0]),
        s_t=np.ones_like(depth),
        hu_mean=np.zeros_like(depth),
        ke_per_mm_s=0.25,
        n_clipped=0,
        n_samples=1,
        calibration="test",
    )
    r = armed(table)
    v = 1.0
    errors = []
    for i in range(1, 60_001):
        now = i * DT
        r.host_frame(now)
        force = r.tick(now, v * now, v)
        if now > 5.0:  # contact after 1.25 s, then 12 time constants
            errors.append(force - force_n(profile, r.front_mm, v, now))
    assert r.state == DeviceState.CUTTING
    assert max(abs(e) for e in errors) < 1e-4
    # the front lags the master by S0 (1 + Ke v) / k, less this tick's advance v dt
    assert r.front_mm == pytest.approx(
        6.0 - 4.0 * 1.25 / 11.0 + v * DT, abs=1e-6
    )  # lags by S0(1+Ke v)/k


def test_stop_depth_is_never_passed_and_the_wall_is_continuous() -> None:
    table = ProfileTable.slab(
        s0_n=2.0, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=5.0, ke_per_mm_s=0.0
    )
    r = armed(table, peak_force_n=1e9, thermal_budget_n2_s=1e9)
    forces = []
    for i in range(1, 200_001):  # master driven to 20 mm at 10 mm/s
        now = i * DT
        r.host_frame(now)
        forces.append(r.tick(now, min(10.0 * now, 20.0), 10.0 if 10.0 * now < 20 else 0.0))
        assert r.drill_mm <= 5.0 and r.front_mm <= 5.0
    assert r.state == DeviceState.STOPPED
    assert r.front_mm == 5.0 and r.drill_mm == 5.0
    steps = np.diff(np.array(forces))[: int(2.0 / DT) - 2]
    # Continuous while the master moves: the coupling adds k * 1 um = 0.011 N per tick at
    # 10 mm/s; beyond the stop's anchor the wall's spring grows by K_w * 3 um (the master's 1 um
    # plus the anchor's 2 um glide back to the stop) = 0.6 N per tick, and its damper, within
    # the spring's force, at most as much: the wall starts from zero. The only steps are where
    # the rigid-plastic front (Ke = 0) starts and stops dead: the damping term b (vm - vf)
    # jumps by b * 10 mm/s = 0.8 N there, over two ticks (down as it starts, up as it stops,
    # with the wall's first ticks).
    start = int(np.argmax(np.abs(steps) > 0.1))
    assert steps[start : start + 2].sum() == pytest.approx(-0.8, abs=0.02)
    wall = STOP_WALL_N_PER_MM * (1e-3 + STOP_GLIDE_MM_S * DT)
    assert np.abs(steps).max() <= 0.8 + 2.0 * wall + 11.0 * 1e-3 + 1e-9
    others = np.delete(steps, [start, start + 1])
    assert np.abs(others).max() > 2.0 * wall - 1e-9  # the wall's growth was reached
    # The master rests 20 mm deep: the anchor has glided to the stop depth, the wall pushes
    # from there (11 N/mm coupling + 200 N/mm wall over the 15 mm past the stop).
    assert r.stop_anchor_mm == 5.0
    assert forces[-1] == pytest.approx((11.0 + STOP_WALL_N_PER_MM) * (20.0 - 5.0), rel=1e-9)
    # Retreat to 5.1 mm: the anchor follows the retreat, then glides to the stop under the
    # resting hand (0.1 mm at 20 mm/s: 50 ticks); push again: the wall is stiff from the stop.
    now = 20.0
    for target in (5.1,) * 60 + (6.1,):
        now += DT
        r.host_frame(now)
        force = r.tick(now, target, 0.0)
    assert r.stop_anchor_mm == 5.0
    assert force == pytest.approx((11.0 + STOP_WALL_N_PER_MM) * 1.1)
    assert r.drill_mm == 5.0


def test_the_stop_anchor_glides_to_the_stop_and_carries_the_hand_back() -> None:
    # The master jumps to 3 mm, past the stop (1 mm), the front still at the surface: the wall
    # starts where the master is (no force step), the drill cuts on to the stop driven by the
    # coupling and the wall, and the anchor glides to the stop at STOP_GLIDE_MM_S: held at 3 mm
    # the master meets a wall force growing by K_w * glide per tick once the front has stopped.
    table = ProfileTable.slab(s0_n=2.0, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=1.0)
    r = armed(table, peak_force_n=1e9, thermal_budget_n2_s=1e9)
    now, anchors, forces, fronts = 0.0, [], [], []
    for _ in range(2000):
        now += DT
        r.host_frame(now)
        forces.append(r.tick(now, 3.0, 0.0))
        anchors.append(r.stop_anchor_mm)
        fronts.append(r.front_mm)
    first = next(i for i, a in enumerate(anchors) if math.isfinite(a))
    assert first == 0 and anchors[first] == 3.0 and r.state == DeviceState.STOPPED
    glide_mm = STOP_GLIDE_MM_S * DT
    n_glide = round(2.0 / glide_mm)
    assert anchors[first + n_glide - 1] == pytest.approx(1.0 + glide_mm, abs=1e-9)
    assert anchors[first + n_glide] == pytest.approx(1.0, abs=1e-9) and anchors[-1] == 1.0
    stopped = next(i for i, f in enumerate(fronts) if f >= 1.0)
    assert stopped < n_glide // 2  # the whole push drives the drill: it reaches the stop early
    rise = np.diff(forces[stopped + 1 : first + n_glide])  # after the tick the front stopped
    assert np.allclose(rise, STOP_WALL_N_PER_MM * glide_mm, atol=1e-9)
    assert forces[-1] == pytest.approx((11.0 + STOP_WALL_N_PER_MM) * 2.0)


@pytest.mark.parametrize("hand_n", [-10.0, 0.0])
def test_the_wall_damper_stays_within_the_spring_force(hand_n: float) -> None:
    # Meeting the wall at 200 mm/s: the damper alone would add 0.4 * 200 = 80 N at once; within
    # the spring's force it starts from zero. Moving out fast, the wall never pulls: with a hand
    # drawing the handle back (-10 N) the force is 0; with the hand off the handle the release
    # damper alone brakes the master (-0.4 N s/mm * 200 mm/s, bounded to the 20 N continuous
    # rating; -0.4 * 30 mm/s within it).
    table = ProfileTable.slab(s0_n=2.0, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=1.0)
    r = armed(table, peak_force_n=1e9, thermal_budget_n2_s=1e9)
    now = 0.0
    for _ in range(3000):  # the front to the stop, the anchor to the stop
        now += DT
        r.host_frame(now)
        r.tick(now, 1.5, 0.0, hand_n)
    assert r.stop_anchor_mm == 1.0
    # the hand eases back onto the stop depth (the anchor follows it there), then moves in
    # 20 um at 200 mm/s: the damper alone would add 0.4 * 200 = 80 N at once. The reading the
    # renderer gets is the observer's: the hand's force less its lag behind the acceleration
    # (0.1 ms * 1000 rad/s * 0.5 kg * a), which the renderer adds back.
    v_prev = 0.0

    def observed(v: float) -> float:
        return hand_n - 1e-4 * 1000.0 * 0.5 * 1e-3 * (v - v_prev) / DT

    for x, v in ((1.0, 0.0), (1.02, 200.0)):
        now += DT
        r.host_frame(now)
        force = r.tick(now, x, v, observed(v))
        v_prev = v
    spring = STOP_WALL_N_PER_MM * 0.02
    assert force == pytest.approx(11.0 * 0.02 + 0.08 * 200.0 + 2.0 * spring)
    for x, v, release in ((1.01, -200.0, -RELEASE_MAX_N), (1.0, -30.0, -12.0)):
        now += DT
        r.host_frame(now)
        assert RELEASE_DAMPING_N_S_PER_MM * v <= release
        expected = release if hand_n == 0.0 else 0.0
        assert r.tick(now, x, v, observed(v)) == pytest.approx(expected, abs=1e-12)
        v_prev = v


def test_peak_and_thermal_limits() -> None:
    table = ProfileTable.slab(s0_n=2.0, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=1.0)
    r = armed(table)
    forces = []
    for i in range(1, 15_001):  # master held 30 mm deep: far past the stop
        now = i * DT
        r.host_frame(now)
        forces.append(r.tick(now, 30.0, 0.0))
    f = np.array(forces)
    assert f.max() == 78.0
    assert r.faults & Fault.PEAK_LIMIT and r.faults & Fault.THERMAL_LIMIT
    # Budget (78^2 - 20^2) N^2 s at 78 N lasts exactly 1 s, then 20 N continuous.
    first_limited = int(np.argmax(f < 78.0))
    assert first_limited * DT == pytest.approx(1.0, abs=2 * DT)
    assert np.all(f[first_limited:] == 20.0)


def test_watchdog_trips_after_50_ms_and_latches_until_rearmed() -> None:
    table = ProfileTable.slab(s0_n=2.0, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=10.0)
    r = armed(table)
    r.host_frame(0.1)
    trip = None
    for i in range(1, 2000):
        now = i * DT
        r.tick(now, 1.0, 0.0)
        if r.state == DeviceState.SAFE:
            trip = now
            break
    assert trip is not None
    assert 0.150 < trip <= 0.150 + DT + 1e-12
    assert r.faults == Fault.WATCHDOG and r.force_cmd_n == 0.0
    r.host_frame(trip)  # a frame after the trip does not clear it
    assert r.tick(trip + DT, 3.0, 0.0) == 0.0 and r.state == DeviceState.SAFE
    assert r.front_mm <= 1.0  # the drill stopped: pushing deeper does not cut
    assert r.drill_mm <= 1.0
    # Re-arming needs the handle retracted: 11 N/mm * (3 - 1) mm = 22 N > 5 N would be a step.
    assert r.arm(trip + 2 * DT, 3.0) == NakReason.NOT_RETRACTED and r.state == DeviceState.SAFE
    assert r.arm(trip + 2 * DT, 1.0) is None
    assert r.state == DeviceState.CUTTING and r.faults == 0


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_nonfinite_input_goes_safe(bad: float) -> None:
    table = ProfileTable.slab(s0_n=2.0, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=10.0)
    r = armed(table)
    r.host_frame(DT)
    assert r.tick(DT, bad, 0.0) == 0.0
    assert r.state == DeviceState.SAFE and r.faults & Fault.NONFINITE
    r2 = armed(table)
    assert r2.tick(DT, 1.0, bad) == 0.0 and r2.faults & Fault.NONFINITE


def test_arm_needs_a_table_and_idle_renders_nothing() -> None:
    r = Renderer()
    assert r.arm(0.0, 0.0) == NakReason.NOT_READY
    assert r.tick(DT, 5.0, 1.0) == 0.0 and r.state == DeviceState.IDLE


@settings(max_examples=60)
@given(
    s0=st.floats(0.0, 60.0),
    ke=st.floats(0.0, 2.0),
    s1=st.floats(-10.0, 10.0),
    stop=st.floats(0.0, 30.0),
    moves=st.lists(
        st.tuples(st.floats(-50.0, 80.0, allow_nan=False), st.floats(-1e4, 1e4)),
        min_size=1,
        max_size=40,
    ),
)
def test_any_trajectory_keeps_force_bounded_and_drill_above_stop(
    s0: float,
    ke: float,
    s1: float,
    stop: float,
    moves: list[tuple[float, float]],
) -> None:
    table = ProfileTable.slab(
        s0_n=s0, s1_n=s1, s2_n=-s1, ke_per_mm_s=ke, top_mm=0.0, bottom_mm=35.0, stop_depth_mm=stop
    )
    r = armed(table)
    now = 0.0
    for master, velocity in moves:
        for _ in range(25):
            now += DT
            r.host_frame(now)
            force = r.tick(now, master, velocity)
            # only the release damper pulls, on a master moving back (the hand off it), and
            # at most the continuous rating
            assert math.isfinite(force) and -RELEASE_MAX_N <= force <= 78.0
            assert force >= 0.0 or velocity < 0.0
            assert r.drill_mm <= table.stop_depth_mm
            assert r.front_mm <= table.stop_depth_mm


@pytest.mark.parametrize("accel_mm_s2", [48_000.0, 0.0])
def test_the_release_gate_reads_through_the_observers_lag(accel_mm_s2: float) -> None:
    # The observer reads a master braked at 20 N (a = Kf 20 N / Mn = 48 m/s^2, no hand) as a
    # steady 2.4 N pull (0.1 ms * 1000 rad/s * 0.5 kg * a): the gate adds that back and its
    # reading is 0, so the damper stays on. The same 2.4 N at rest (no acceleration) is a hand
    # pulling: the damper switches off after the hold (80 ticks), and on again when it stops.
    table = ProfileTable.slab(s0_n=2.0, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=30.0)
    r = armed(table)
    now, v = 0.0, -1500.0
    for _ in range(400):  # moving back steadily, no hand
        now += DT
        r.host_frame(now)
        r.tick(now, -1.0, v, 0.0)
    assert r.release_gain() == 1.0
    switched_off = None
    for i in range(1, 2001):
        now += DT
        r.host_frame(now)
        v += accel_mm_s2 * DT
        r.tick(now, -1.0, v, -2.4)
        if switched_off is None and r.release_gain() == 0.0:
            switched_off = i
    if accel_mm_s2:
        assert switched_off is None and abs(r.hand_n) < 1e-6
    else:
        assert r.hand_n == pytest.approx(-2.4)
        # the filtered reading passes -2 N after 18 ticks (1 - 0.9^n > 2 / 2.4), then the hold
        assert switched_off == 18 + RELEASE_HOLD_TICKS - 1
    for _ in range(30):  # the hand lets go: on again once the reading is within 1 N
        now += DT
        r.host_frame(now)
        r.tick(now, -1.0, v, 0.0)
    assert r.release_gain() == 1.0
