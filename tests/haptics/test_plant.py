"""The master plant (Table 4) and its DOB/RFOB force controller."""

from __future__ import annotations

import pytest

from ctdrill.haptics.plant import ENCODER_M, ForceController, MasterPlant

DT = 1e-4


def test_encoder_quantises_to_a_tenth_of_a_micrometre() -> None:
    p = MasterPlant(start_mm=1.23456789)
    assert p.encoder_mm() == pytest.approx(1.2346, abs=1e-12)  # 0.1 um = 1e-4 mm
    assert ENCODER_M == 1e-7


def test_coulomb_friction_sticks_below_1_n_and_slides_above() -> None:
    p = MasterPlant()
    for _ in range(1000):
        p.step(0.0, 0.99, DT)
    assert p.x_m == 0.0 and p.v_m_s == 0.0
    p.step(0.0, 3.0, DT)  # (3 - 1) N / 0.5 kg = 4 m/s^2 held for one step (exact: a t^2 / 2)
    assert p.v_m_s == pytest.approx(4.0 * DT)
    assert p.x_m == pytest.approx(0.5 * 4.0 * DT * DT)
    # Motor force counts like the hand's: 1/33 A is 1 N.
    q = MasterPlant()
    q.step(3.0 / 33.0, 0.0, DT)
    assert q.v_m_s == pytest.approx(4.0 * DT)
    # Friction (2 m/s^2 on 0.5 kg) stops the stage in two steps; it never reverses it, and it
    # stops where a uniform deceleration does: 4 DT^2 / 2 + (4 DT)^2 / (2 * 2) = 6 DT^2.
    q.step(0.0, 0.0, DT)
    assert q.v_m_s == pytest.approx(2.0 * DT)
    q.step(0.0, 0.0, DT)
    q.step(0.0, 0.0, DT)
    assert q.v_m_s == 0.0
    assert q.x_m == pytest.approx(6.0 * DT * DT)


def test_end_stops() -> None:
    p = MasterPlant(start_mm=59.99)
    for _ in range(2000):
        p.step(0.0, 20.0, DT)
    assert p.position_mm == pytest.approx(60.0) and p.at_end_stop and p.v_m_s == 0.0


def test_force_control_makes_an_apparent_mass() -> None:
    # Free space (F_cmd = 0), hand 5 N: the DOB cancels friction and force control gives
    # a = Kf F / Mn = 1.2 * 5 / 0.5 = 12 m/s^2 (within the observers' lag under acceleration).
    p = MasterPlant()
    c = ForceController()
    v_at = {}
    for i in range(1, 1001):
        p.step(c.update(p.encoder_mm(), 0.0), 5.0, DT)
        if i in (200, 1000):
            v_at[i] = p.v_m_s
    accel = (v_at[1000] - v_at[200]) / (800 * DT)
    assert accel == pytest.approx(12.0, rel=0.03)


def test_a_rendered_spring_holds_the_hand_within_friction() -> None:
    # Hand 7 N against a rendered wall at 1 mm (11 N/mm, 0.08 N s/mm, the cutting coupling):
    # the stage settles at 1 + 7 / 11 mm, within the Coulomb band of +-1 N / 11 N/mm, the
    # RFOB reading the hand within the friction, and stays there.
    p = MasterPlant()
    c = ForceController()

    def wall() -> float:
        e = p.encoder_mm() - 1.0
        return max(0.0, 11.0 * e + 0.08 * c.velocity_mm_s) if e > 0.0 else 0.0

    for _ in range(10_000):
        p.step(c.update(p.encoder_mm(), wall()), 7.0, DT)
    settled = p.position_mm
    assert settled == pytest.approx(1.0 + 7.0 / 11.0, abs=1.0 / 11.0)
    assert c.hand_est_n == pytest.approx(7.0, abs=1.0)
    for _ in range(5_000):
        p.step(c.update(p.encoder_mm(), wall()), 7.0, DT)
    assert p.position_mm == pytest.approx(settled, abs=1e-3)
