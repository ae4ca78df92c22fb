"""The slave under bilateral control: channel, Eq. 25, replay, the force-based stop."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.teleop import TeleopCase, prepare_teleop, run_teleop
from ctdrill.haptics.bilateral.channel import Channel
from ctdrill.haptics.bilateral.estimator import HuEstimator
from ctdrill.haptics.bilateral.params import ChannelSpec
from ctdrill.haptics.bilateral.prior import plan_prior
from ctdrill.haptics.bilateral.servo import (
    SERVO_FRICTION_RELAX_S,
    SERVO_FRICTION_TRAVEL_M,
    Servo,
)
from ctdrill.haptics.bilateral.stability import SPREAD_LIMIT_UM, stability_point
from ctdrill.haptics.session import parse_operator
from ctdrill.model.calibration import load_calibration
from ctdrill.model.force import a0_n
from ctdrill.model.profile import build_profile

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


def test_servo_friction_model_follows_travel_and_relaxes_at_rest() -> None:
    """No current, an encoder ramp at v: the RFOB's external force is the friction model alone,
    which settles at ``Fc v tau / (x0 + v tau)`` (its travel gain against its relaxation, per
    tick) and then decays as ``exp(-t / tau)`` once the stage rests."""
    dt = 1e-4
    fc = 1.0
    servo = Servo(
        mass_kg=1.2, kt_n_per_a=33.0, coulomb_n=fc, current_limit_a=4.5,
        g_dob=1000.0, g_rfob=1000.0, g_vel=1000.0, dt_s=dt, start_mm=0.0,
    )  # fmt: skip
    v_mm_s = 0.4
    x_mm = 0.0
    for _ in range(20_000):  # 2 s: 40 relaxation times
        x_mm += v_mm_s * dt
        servo.observe(x_mm)
    a = v_mm_s * 1e-3 * dt / SERVO_FRICTION_TRAVEL_M
    b = dt / SERVO_FRICTION_RELAX_S
    z_ss = a * (1.0 - b) / (a * (1.0 - b) + b)  # fixed point of z += a (1 - z); z -= b z
    assert servo.external_n == pytest.approx(fc * z_ss, rel=1e-6)
    assert z_ss > 0.9  # a slow feed has nearly all its friction modelled
    for _ in range(1000):  # 0.1 s at rest (the velocity observer settles in ~5 ms)
        servo.observe(x_mm)
    assert servo.external_n == pytest.approx(fc * z_ss * math.exp(-2.0), rel=0.02)


def test_channel_delays_by_whole_ticks_keeps_order_and_holds_over_loss() -> None:
    ch = Channel(ChannelSpec(delay_ms=0.5), 10_000.0, seed=1, initial=(0.0, 0.0, 0.0))
    got = []
    for k in range(10):
        ch.send(k, (float(k), 0.0, 0.0))
        got.append(ch.receive(k)[0])
    assert got == [0.0] * 5 + [0.0, 1.0, 2.0, 3.0, 4.0]  # 5 ticks late
    lossy = Channel(ChannelSpec(loss=0.5, jitter_ms=2.0), 10_000.0, 3, (0.0, 0.0, 0.0))
    seen = []
    for k in range(2000):
        lossy.send(k, (float(k), 0.0, 0.0))
        seen.append(lossy.receive(k)[0])
    assert all(b >= a for a, b in itertools.pairwise(seen))  # never out of order
    assert 800 < lossy.lost < 1200


def _slab_prior(hu: float):  # type: ignore[no-untyped-def]
    cal = load_calibration("bone-illustrative")
    depth = np.arange(0.0, 20.0, 0.05)
    lip = np.full((depth.size, 1, 1), hu)
    prof = build_profile(lip, np.ones(1), depth, cal, blades=2, rpm=900)
    return cal, plan_prior(prof, cal)


@pytest.mark.parametrize("gain", [0.8, 1.0, 1.25])
def test_eq25_inverts_eq20_and_learns_the_force_gain(gain: float) -> None:
    # a steady cut of 1050 HU at 0.5 mm/s whose force law is `gain` times the model's
    cal, prior = _slab_prior(1050.0)
    est = HuEstimator(cal, prior, tip_length_mm=0.6, window_ticks=333, tick_s=1e-4)
    force = gain * float(a0_n(1050.0, 0.5, cal))
    for k in range(60_000):
        x = 1.0 + 0.5 * k * 1e-4
        f = force * min(1.0, (x - 1.0) / 0.6)  # the lip engages (Eq. 2)
        est.update(x + f / 100.0, f)
    assert est.valid and est.stop_reason is None
    assert 10.0**est.log10_gain == pytest.approx(gain, rel=1e-9)
    assert est.hu == pytest.approx(1050.0, abs=1e-6)


def test_a_force_that_vanishes_after_bone_is_a_cortex_exit() -> None:
    cal, prior = _slab_prior(1050.0)
    est = HuEstimator(cal, prior, tip_length_mm=0.6, window_ticks=333, tick_s=1e-4)
    force = float(a0_n(1050.0, 0.5, cal))
    k = 0
    while est.stop_reason is None and k < 80_000:
        x = 1.0 + 0.5 * k * 1e-4
        f = force * min(1.0, (x - 1.0) / 0.6, max(0.0, 1.0 - (x - 3.0) / 0.6))
        est.update(x + f / 100.0, f)
        k += 1
    assert est.stop_reason == "cortex_exit"
    assert 3.0 < 1.0 + 0.5 * k * 1e-4 < 3.6


def test_a_front_slowing_down_in_bone_is_no_cortex_exit() -> None:
    """A push meets the bone at 60 mm/s and slows to 3 mm/s in it (as on the Philips head
    phantom, below): the force falls with the feed's factor, not the material; the fast exit
    test compared it with the exit level's force at the window's mean feed, 33 ms behind."""
    cal, prior = _slab_prior(1050.0)
    est = HuEstimator(cal, prior, tip_length_mm=0.6, window_ticks=333, tick_s=1e-4)
    x = 0.0
    for _ in range(5000):
        feed = 60.0 if x < 4.0 else 3.0
        x += feed * 1e-4
        f = 0.8 * float(a0_n(1050.0, feed, cal)) * min(1.0, max(0.0, (x - 1.0) / 0.6))
        est.update(x + f / 100.0, f)
    assert est.stop_reason is None
    assert x > 4.1 and est.hu == pytest.approx(1050.0, abs=1.0)


def test_a_plunge_through_the_exit_is_stopped_past_the_breakthrough_and_soon() -> None:
    """The lip leaves a slab at 3.0-3.6 mm while the front jumps from 10 to 60 mm/s (the plunge
    after a breakthrough): the sessions' breakthrough (the force at rest below half its peak)
    is at 3.3 mm; the fast test reads the force at the plunge's feed, so the stop comes past
    it, 0.13 mm past (with the window's mean feed, 33 ms behind: 0.24 mm)."""
    cal, prior = _slab_prior(1050.0)
    est = HuEstimator(cal, prior, tip_length_mm=0.6, window_ticks=333, tick_s=1e-4)
    x = 0.0
    while est.stop_reason is None and x < 4.0:
        feed = 10.0 if x < 3.0 else 60.0
        x += feed * 1e-4
        s_t = min(1.0, max(0.0, (x - 1.0) / 0.6), max(0.0, 1.0 - (x - 3.0) / 0.6))
        f = float(a0_n(1050.0, feed, cal)) * s_t
        est.update(x + f / 100.0, f)
    assert est.stop_reason == "cortex_exit"
    assert 3.3 <= x <= 3.45


def test_a_push_on_the_philips_phantom_is_not_stopped_in_bone(shared_data: Path) -> None:
    """``push:20`` with the force law 20 % low on the real Philips head CT: the front meets the
    bone at ~180 mm/s and slows in it; it was stopped 2.1 mm into bone as ``cortex_exit``
    (the CT shows no exit before the plan's stop)."""
    case = prepare_teleop(
        shared_data / "dcmqa_ct_Philips_phantom_notilt_5mm",
        ROOT / "tests" / "data" / "philips_head_arch.plan.json",
    )
    assert case.exit_mm is None
    run, f = run_teleop(case, parse_operator("push:20"), duration_s=0.25, model_error=-0.2)
    assert f["stop_reason"] == "none"  # 0.25 s: 3 mm into bone, the plan's stop not yet reached
    assert run.front_mm[-1] > case.prior.contact_mm + 2.5


def _drill(
    est: HuEstimator, force_at: Callable[[float], float], x0: float, feed_mm_s: float, ticks: int
) -> None:
    for k in range(ticks):
        x = x0 + feed_mm_s * k * 1e-4
        f = force_at(x)
        est.update(x + f / 100.0, f)


def test_a_start_transient_is_not_the_contact() -> None:
    """The RFOB reads the start of a motion as a force (over 1 N for a window) in free flight;
    the contact it would place there is dropped when the force lets go before the lip engages,
    and the real one is found where the force rises."""
    cal, prior = _slab_prior(1050.0)
    est = HuEstimator(cal, prior, tip_length_mm=0.6, window_ticks=333, tick_s=1e-4)
    full = float(a0_n(1050.0, 0.5, cal))
    surface = 1.0

    def force(x: float) -> float:
        if x < 0.02:  # the start: 3 N over 0.02 mm of free flight
            return 3.0
        return full * min(1.0, max(0.0, (x - surface) / 0.6))

    _drill(est, force, 0.0, 0.5, 40_000)  # to 2 mm
    at_rest = float(a0_n(1050.0, 0.0, cal))  # the force at rest passes 1 N there:
    assert surface < est.contact_mm < surface + 0.6 / at_rest + 0.01
    assert est.hu == pytest.approx(1050.0, abs=1.0)


@pytest.mark.parametrize("feed_mm_s", [0.5, 20.0, 70.0])
def test_the_contact_is_where_the_force_at_rest_passes_1_n_whatever_the_approach(
    feed_mm_s: float,
) -> None:
    """A push meets the surface at 30-80 mm/s, where Eq. 20's ``1 + Ke v`` multiplies the force
    by up to 13.5: the raw force passes 1 N when the lip has barely touched. The contact is
    placed where the force at rest, ``F / (1 + Ke v)``, passes 1 N, as at a slow feed and as
    the plan's contact (:attr:`Prior.contact_mm`) is defined, so an impact is not read as a
    plan registered ~0.1 mm shallower and the lip's engagement is not overestimated."""
    cal, prior = _slab_prior(1050.0)
    est = HuEstimator(cal, prior, tip_length_mm=0.6, window_ticks=333, tick_s=1e-4)
    surface = 1.0
    full = float(a0_n(1050.0, feed_mm_s, cal))
    at_rest = float(a0_n(1050.0, 0.0, cal))
    ticks = round((surface + 0.8) / feed_mm_s * 1e4)
    _drill(est, lambda x: full * min(1.0, max(0.0, (x - surface) / 0.6)), 0.0, feed_mm_s, ticks)
    # where the force at rest passes 1 N: within a tick's travel and a few um
    assert est.contact_mm == pytest.approx(surface + 0.6 / at_rest, abs=feed_mm_s * 1e-4 + 0.005)
    assert est.registration_mm == pytest.approx(est.contact_mm - prior.contact_mm)


@pytest.mark.parametrize("shift_mm", [-1.0, 1.5])
def test_the_plan_is_registered_by_the_contact_so_the_gain_learns_in_the_first_layer(
    shift_mm: float,
) -> None:
    """The plan shows a 1050 HU slab from 3 mm; the slave meets it ``shift_mm`` shallower and
    its force law is 20 % high. Registered by the contact, the first layer's votes agree with
    the plan and the gain is learnt there; without it they would be read against air."""
    cal = load_calibration("bone-illustrative")
    depth = np.arange(0.0, 12.0, 0.05)
    lip = np.where(depth >= 3.0, 1050.0, -1000.0).reshape(-1, 1, 1)
    prior = plan_prior(build_profile(lip, np.ones(1), depth, cal, blades=2, rpm=900), cal)
    assert prior.contact_mm == pytest.approx(3.0)
    est = HuEstimator(cal, prior, tip_length_mm=0.6, window_ticks=333, tick_s=1e-4)
    full = 1.2 * float(a0_n(1050.0, 0.5, cal))
    surface = 3.0 - shift_mm
    _drill(est, lambda x: full * min(1.0, max(0.0, (x - surface) / 0.6)), 1.0, 0.5, 80_000)
    # the plan's force jumps at its surface, the slave's ramps over the lip: its force at
    # rest passes 1 N 0.6 / (1.2 A0) mm in
    ramp_mm = 0.6 / (1.2 * float(a0_n(1050.0, 0.0, cal)))
    assert est.registration_mm == pytest.approx(ramp_mm - shift_mm, abs=0.01)
    assert est.gain_updates > 0 and est.votes_rejected == 0
    assert 10.0**est.log10_gain == pytest.approx(1.2, rel=1e-9)
    assert est.hu == pytest.approx(1050.0, abs=1e-6)


@pytest.mark.parametrize(("feed_mm_s", "window_ticks"), [(12.0, 166), (2.0, 333)])
def test_a_fast_front_is_read_over_half_a_rotation(feed_mm_s: float, window_ticks: int) -> None:
    """1050 HU then 800 HU from 3 mm, the force law exact and instantaneous: on each plateau
    the estimate is the CT number exactly (the force over the regressor ``s_t (1 + Ke v)``),
    and it crosses the mid-level a moving average's delay after the front: over half a
    rotation at 12 mm/s, over the whole rotation at 2 mm/s."""
    cal, prior = _slab_prior(1050.0)
    est = HuEstimator(cal, prior, tip_length_mm=0.6, window_ticks=333, tick_s=1e-4)

    def force(x: float) -> float:
        hu = 1050.0 if x < 3.0 else 800.0
        return float(a0_n(hu, feed_mm_s, cal)) * min(1.0, max(0.0, (x - 1.0) / 0.6))

    x = 0.9
    crossed = math.nan
    hu_before = math.nan
    while x < 3.5:
        f = force(x)
        est.update(x + f / 100.0, f)
        if x < 2.99:
            hu_before = est.hu
        if math.isnan(crossed) and x > 3.0 and est.hu < 925.0:
            crossed = x
        x += feed_mm_s * 1e-4
    assert hu_before == pytest.approx(1050.0, abs=1e-6)
    assert est.stop_reason is None and est.hu == pytest.approx(800.0, abs=1e-6)
    # the share p of the window in the new layer at which the mean force (C'^2, n = 2) is
    # the mid-level's: (1 - p) 2050^2 + p 1800^2 = 1925^2
    p = (2050.0**2 - 1925.0**2) / (2050.0**2 - 1800.0**2)
    delay_mm = feed_mm_s * 1e-4 * window_ticks * p
    assert crossed - 3.0 == pytest.approx(delay_mm, abs=feed_mm_s * 2e-4)


@pytest.fixture(scope="module")
def case() -> TeleopCase:
    return prepare_teleop(DEMO / "ct", DEMO / "plan.json")


def test_a_seeded_run_replays_bit_for_bit(case: TeleopCase) -> None:
    op = parse_operator("human:force=15,react_ms=150,noise_n=1,seed=4")
    kw = {"duration_s": 0.6, "delay_ms": 1.0, "jitter_ms": 0.5, "loss": 0.05, "record_every": 1}
    a, fa = run_teleop(case, op, seed=7, **kw)  # type: ignore[arg-type]
    b, fb = run_teleop(case, op, seed=7, **kw)  # type: ignore[arg-type]
    c, _ = run_teleop(case, op, seed=8, **kw)  # type: ignore[arg-type]
    for name in ("master_mm", "slave_mm", "env_force_n", "hand_n", "fe_est_n", "energy_j"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(a.hu_est, b.hu_est, equal_nan=True)
    assert fa == fb
    assert not np.array_equal(a.slave_mm, c.slave_mm)  # the seed matters


def test_cutting_is_transparent_without_delay(case: TeleopCase) -> None:
    run, f = run_teleop(case, parse_operator("push:15"), duration_s=1.5)
    cut = f["transparency"]["cutting"]
    assert cut["samples"] > 1000
    assert cut["force_error_pct"] < 3.5  # the paper's figure, mean force
    assert cut["tracking_rms_um"] < 30.0
    assert run.front_mm[-1] > 2.0  # it cut through the cortex


def test_the_force_stop_catches_the_exit_a_misregistered_plan_would_pass() -> None:
    shifted = prepare_teleop(DEMO / "ct", DEMO / "plan.json", misregister_mm=3.0)
    exit_mm = shifted.exit_mm
    assert exit_mm is not None and exit_mm < shifted.plan_path.stop_depth_mm  # the plan's stop
    op = parse_operator("push:15")
    plan_only, f0 = run_teleop(shifted, op, duration_s=3.0, force_stop=False)
    assert f0["stop_reason"] == "plan_stop" and plan_only.deepest_front_mm > exit_mm + 0.3
    run, f = run_teleop(shifted, op, duration_s=3.0)
    assert f["stop_reason"] == "cortex_exit"
    assert 0.0 <= f["overshoot_mm"] <= 0.5
    assert f["stop_depth_mm"] < shifted.plan_path.stop_depth_mm
    assert math.isfinite(run.stop_time_s)


@pytest.mark.parametrize(
    ("hand", "contact", "delay", "passive", "stable"),
    [
        (20.0, 100.0, 0.0, True, True),  # firm hand, stiff contact, no delay
        (50.0, 11.0, 0.0, True, True),
        (20.0, 100.0, 5.0, False, False),  # 5 ms one way: a limit cycle of ~0.7 mm
        (2.0, 100.0, 20.0, False, False),
    ],
)
def test_points_of_the_stability_map(
    hand: float, contact: float, delay: float, passive: bool, stable: bool
) -> None:
    p = stability_point(hand, contact, delay)
    assert (p.passive, p.stable) == (passive, stable), p
    if not stable:
        assert p.spread_um > 5 * SPREAD_LIMIT_UM  # far from the limit, not a borderline call
    else:
        assert p.spread_um < SPREAD_LIMIT_UM / 5
