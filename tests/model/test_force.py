"""The force law on CT numbers: exact values from Eq. 20-22 with C' = HU + 1000."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ctdrill.model import a0_n, bk_n, c_prime, clip_count, gate, harmonic_freqs_hz, load_calibration
from ctdrill.model.force import (
    MAX_FEED_MM_S,
    feed_factor,
    force_density_n,
    out_of_range,
    phase_rad,
    slab_force_n,
)

PINE = load_calibration("pine-wood-paper")
BONE = load_calibration("bone-illustrative")
FREQS = harmonic_freqs_hz(PINE, blades=2, rpm=900)


def test_c_prime_is_hu_plus_1000() -> None:
    np.testing.assert_array_equal(c_prime([-1000, 0, 1500]), [0.0, 1000.0, 2500.0])


@pytest.mark.parametrize("hu", [-900.0, -700.0, -600.0, -500.0])
def test_a0_is_eq_20(hu: float) -> None:
    cp = hu + 1000.0
    for v in (0.0, 0.1, 0.4):
        expected = 10**-1.35 * cp**0.77 * (1 + 0.25 * v)
        assert float(a0_n(hu, v, PINE)) == pytest.approx(expected, rel=1e-12)


def test_papers_pine_wood_force_level() -> None:
    # DESIGN.md 1.1: pine-wood C' 300..500 gives A0 of about 3.6..5.3 N (zero feed).
    assert float(a0_n(-700, 0.0, PINE)) == pytest.approx(3.61, abs=0.01)
    assert float(a0_n(-500, 0.0, PINE)) == pytest.approx(5.35, abs=0.01)


def test_bk_are_eq_21_22_with_shape_k_by_hu() -> None:
    hu = np.array([[-700.0, -600.0, -500.0]])
    bk = bk_n(hu, PINE)
    assert bk.shape == (2, 1, 3)
    cp = hu + 1000
    np.testing.assert_allclose(bk[0], 10**3.92 * cp**-1.91, rtol=1e-12)
    np.testing.assert_allclose(bk[1], 10**1.72 * cp**-1.29, rtol=1e-12)


def test_gate_ramp_values() -> None:
    # pine: gate -900, width 50 -> 0 at -925, 0.5 at -900, 1 at -875.
    np.testing.assert_allclose(
        gate([-1000, -925, -912.5, -900, -887.5, -875, 0], PINE),
        [0.0, 0.0, 0.25, 0.5, 0.75, 1.0, 1.0],
        atol=1e-15,
    )


def test_power_laws_clip_c_prime_and_count_only_cut_samples() -> None:
    lo, hi = BONE.c_prime_range  # 1100..3100 -> HU 100..2100
    # HU 120 is out of range (C' 1120 is in; 100 would be the edge). Build explicit cases:
    hu = np.array([-1000.0, 0.0, 140.0, 200.0, 2000.0, 2500.0, 32767.0])
    # -1000, 0: below the gate (not cut) -> not counted although C' < lo.
    # 140: gate 0.3 (cut), C' 1140 in range. 2500, 32767: cut, above range -> counted.
    assert clip_count(hu, BONE) == 2
    np.testing.assert_array_equal(
        out_of_range(hu, BONE), [False, False, False, False, False, True, True]
    )
    assert float(a0_n(32767.0, 0.0, BONE)) == pytest.approx(10**BONE.a0.b0 * hi**2.0)
    assert float(a0_n(-32768.0, 0.0, BONE)) == pytest.approx(10**BONE.a0.b0 * lo**2.0)
    assert np.all(np.isfinite(bk_n(np.array([-32768.0, -1000.0]), PINE)))


def test_feed_factor_caps_and_ignores_retraction() -> None:
    np.testing.assert_allclose(
        feed_factor([-5.0, 0.0, 0.4, 1e300], ke_per_mm_s=0.25),
        [1.0, 1.0, 1.1, 1.0 + 0.25 * MAX_FEED_MM_S],
    )


def test_phase_is_reduced_but_exact_for_moderate_times() -> None:
    t = np.array([0.0, 0.001, 0.0125, 1.2345])
    np.testing.assert_allclose(
        np.sin(phase_rad([30.0], t)[0]), np.sin(2 * np.pi * 30.0 * t), atol=1e-12
    )
    assert np.all(np.isfinite(np.sin(phase_rad(FREQS, np.array([1e300, -1e308])))))


def test_force_density_is_gated_eq_19() -> None:
    t = np.array([0.0, 0.004, 0.01])
    hu = -600.0
    cp = 400.0
    expected = (
        10**-1.35 * cp**0.77 * (1 + 0.25 * 0.4)
        + 10**3.92 * cp**-1.91 * np.sin(2 * np.pi * 30 * t)
        + 10**1.72 * cp**-1.29 * np.sin(2 * np.pi * 60 * t)
    )
    got = force_density_n(hu, 0.4, t, PINE, freqs_hz=FREQS)
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    assert np.all(force_density_n(-950.0, 0.4, t, PINE, freqs_hz=FREQS) == 0.0)
    # At the gate centre half the material is cut: g = 0.5 times the law at C' = 100.
    half = force_density_n(-900.0, 0.4, t, PINE, freqs_hz=FREQS)
    law = (
        10**-1.35 * 100**0.77 * 1.1
        + 10**3.92 * 100**-1.91 * np.sin(2 * np.pi * 30 * t)
        + 10**1.72 * 100**-1.29 * np.sin(2 * np.pi * 60 * t)
    )
    np.testing.assert_allclose(half, 0.5 * law, rtol=1e-12)


def test_force_density_checks_frequency_count() -> None:
    with pytest.raises(ValueError, match="freqs_hz"):
        force_density_n(0.0, 0.0, 0.0, PINE, freqs_hz=[30.0])


def test_slab_reference_is_eq_2_to_4() -> None:
    x = np.array([-0.1, 0.0, 0.3, 0.6, 2.0, 5.0, 5.3, 5.6, 6.0])
    f = slab_force_n(x, -600.0, 0.0, 0.0, PINE, thickness_mm=5.0, tip_length_mm=0.6, freqs_hz=FREQS)
    a0 = 10**-1.35 * 400**0.77
    np.testing.assert_allclose(f / a0, [0.0, 0.0, 0.5, 1.0, 1.0, 1.0, 0.5, 0.0, 0.0], atol=1e-12)
    with pytest.raises(ValueError, match="tip_length"):
        slab_force_n(x, 0.0, 0.0, 0.0, PINE, thickness_mm=0.5, tip_length_mm=0.6, freqs_hz=FREQS)


def test_bone_forces_in_published_thrust_range() -> None:
    # DESIGN.md: about 2 N in D4 bone, about 8-11 N in D1 (at 0.6 mm/s).
    assert 1.5 < float(a0_n(250.0, 0.6, BONE)) < 2.5
    assert float(a0_n(1500.0, 0.6, BONE)) + 1e-3 >= 8.0
    assert float(a0_n(2000.0, 0.6, BONE)) < 12.0
    assert math.isfinite(float(a0_n(1500.0, 0.6, BONE)))
