"""Profiles from lip samples: exact in homogeneous material, O(1) force_n, vectorised series."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.model import (
    Calibration,
    ModelInputError,
    Profile,
    a0_n,
    bk_n,
    build_profile,
    force_n,
    force_series_n,
    gate,
    harmonic_freqs_hz,
    load_calibration,
)
from ctdrill.model.force import MAX_FEED_MM_S
from tests.model.lip import layered_lip_hu

PINE = load_calibration("pine-wood-paper")
BONE = load_calibration("bone-illustrative")
DEPTH = np.arange(0.0, 10.0 + 1e-9, 0.05)


def _eq19(hu: float, feed: float, t: float) -> float:
    """Eq. 19 with Eq. 20-22 written out from the paper (s_t = 1)."""
    cp = hu + 1000.0
    return (
        10**-1.35 * cp**0.77 * (1 + 0.25 * feed)
        + 10**3.92 * cp**-1.91 * np.sin(2 * np.pi * 30 * t)
        + 10**1.72 * cp**-1.29 * np.sin(2 * np.pi * 60 * t)
    )


def _uniform(hu: float, d: int = 5, r: int = 4, a: int = 8) -> np.ndarray:
    return np.full((d, r, a), hu)


def test_homogeneous_material_is_eq_19_exactly() -> None:
    depth = np.linspace(1.0, 3.0, 5)
    p = build_profile(_uniform(-600.0), np.full(4, 0.25), depth, PINE, blades=2, rpm=900)
    np.testing.assert_allclose(p.s_t, 1.0, rtol=1e-15)
    np.testing.assert_allclose(p.hu_mean, -600.0, rtol=1e-15)
    np.testing.assert_array_equal(p.freqs_hz, [30.0, 60.0])
    for x in (1.0, 1.7, 3.0):
        for feed, t in ((0.0, 0.0), (0.4, 0.0123), (0.25, 7.31)):
            assert force_n(p, x, feed, t) == pytest.approx(_eq19(-600.0, feed, t), abs=1e-9)
    assert (p.n_clipped, p.n_samples) == (0, 5 * 4 * 8)


def test_slab_interior_exact_and_ramps_with_rings() -> None:
    lip, w = layered_lip_hu([0.0, 5.0], [-600.0], DEPTH, tip_length_mm=0.6, n_rings=6)
    p = build_profile(lip, w, DEPTH, PINE, blades=2, rpm=900)
    inside = (DEPTH >= 0.6) & (DEPTH <= 5.0)
    np.testing.assert_allclose(p.s0_n[inside], _eq19(-600.0, 0.0, 0.0), rtol=1e-12)
    # Six midpoint rings: x = 0.3 -> 3 rings at depth >= 0 -> s_t = 1/2 (Eq. 2 gives 0.5).
    assert p.s_t[6] == pytest.approx(0.5)  # DEPTH[6] = 0.3
    assert p.s_t[0] == 0.0
    assert np.all(p.s0_n[DEPTH > 5.6 + 1e-9] == 0.0)


def test_gate_and_mixed_rings_weighted_mean() -> None:
    # Ring 0 (weight 0.25) in material, ring 1 (weight 0.75) in air; angles half/half.
    lip = np.empty((2, 2, 2))
    lip[:, 0, :] = -600.0
    lip[:, 1, 0] = -1000.0
    lip[:, 1, 1] = -900.0  # gate centre: g = 0.5
    p = build_profile(lip, [0.25, 0.75], [0.0, 1.0], PINE, blades=2, rpm=900)
    a0_600 = 10**-1.35 * 400**0.77
    a0_900 = 10**-1.35 * 100**0.77
    np.testing.assert_allclose(p.s_t, 0.25 + 0.75 * 0.25)
    np.testing.assert_allclose(p.s0_n, 0.25 * a0_600 + 0.75 * 0.5 * 0.5 * a0_900)
    np.testing.assert_allclose(p.hu_mean, 0.25 * -600 + 0.75 * -950)


def test_clipped_samples_counted_only_when_cut() -> None:
    lip = np.full((2, 1, 4), -1000.0)  # air: C' = 0 < lo but not cut
    lip[1, 0, :2] = 2500.0  # cut, C' 3500 > 3100
    p = build_profile(lip, [1.0], [0.0, 0.1], BONE, blades=2, rpm=900)
    assert (p.n_clipped, p.n_samples) == (2, 8)
    assert np.all(np.isfinite(p.s0_n)) and np.all(np.isfinite(p.sk_n))


def test_force_n_interpolates_linearly_and_is_zero_outside() -> None:
    depth = np.array([2.0, 2.5, 3.0])
    p = Profile(
        depth_mm=depth,
        s0_n=np.array([1.0, 3.0, 2.0]),
        sk_n=np.array([[0.0, 1.0, 0.0]]),
        freqs_hz=np.array([10.0]),
        s_t=np.ones(3),
        hu_mean=np.zeros(3),
        ke_per_mm_s=0.5,
        n_clipped=0,
        n_samples=3,
        calibration="test",
    )
    assert p.step_mm == pytest.approx(0.5)
    assert force_n(p, 2.25, 0.0, 0.0) == pytest.approx(2.0)
    assert force_n(p, 2.25, 2.0, 0.0) == pytest.approx(4.0)
    assert force_n(p, 3.0, 0.0, 0.0) == pytest.approx(2.0)
    assert force_n(p, 2.5, 0.0, 0.025) == pytest.approx(3.0 + 1.0)  # sin(pi / 2)
    assert force_n(p, 2.75, 0.0, 0.025) == pytest.approx(2.5 + 0.5)
    for x in (1.99, 3.01, float("nan"), float("inf"), -float("inf")):
        assert force_n(p, x, 0.4, 0.1) == 0.0
    # Retraction: no negative feed factor; absurd feeds capped; NaN feed/time harmless.
    assert force_n(p, 2.0, -100.0, 0.0) == pytest.approx(1.0)
    assert force_n(p, 2.0, 1e300, 0.0) == pytest.approx(1.0 + 0.5 * MAX_FEED_MM_S)
    assert force_n(p, 2.0, float("nan"), 0.0) == pytest.approx(1.0)
    assert force_n(p, 2.5, 0.0, float("nan")) == pytest.approx(3.0)
    # The vectorised series agrees with the scalar path everywhere.
    x = np.linspace(1.5, 3.5, 101)
    t = np.linspace(0.0, 0.3, 101)
    v = np.linspace(-1.0, 2.0, 101)
    expected = [force_n(p, float(a), float(b), float(c)) for a, b, c in zip(x, v, t, strict=True)]
    np.testing.assert_allclose(force_series_n(p, x, v, t), expected, rtol=1e-12, atol=1e-12)


def test_profile_arrays_are_read_only_copies() -> None:
    s0 = np.array([1.0, 2.0])
    p = Profile(
        depth_mm=np.array([0.0, 1.0]),
        s0_n=s0,
        sk_n=np.zeros((0, 2)),
        freqs_hz=np.zeros(0),
        s_t=np.ones(2),
        hu_mean=np.zeros(2),
        ke_per_mm_s=0.0,
        n_clipped=0,
        n_samples=2,
        calibration="x",
    )
    s0[0] = 99.0
    assert p.s0_n[0] == 1.0
    with pytest.raises(ValueError, match="read-only"):
        p.s0_n[0] = 5.0
    assert force_n(p, 0.5, 0.0, 0.0) == pytest.approx(1.5)


def test_series_on_real_time_axis_matches_eq_19() -> None:
    lip, w = layered_lip_hu([0.0, 20.0], [-600.0], DEPTH, tip_length_mm=0.6, n_rings=4)
    p = build_profile(lip, w, DEPTH, PINE, blades=2, rpm=900)
    t = np.arange(0.0, 5.0, 1e-3)
    x = 1.0 + 0.4 * t
    expected = _eq19(-600.0, 0.4, t)
    np.testing.assert_allclose(force_series_n(p, x, 0.4, t), expected, atol=1e-9)
    freqs = harmonic_freqs_hz(PINE, blades=2, rpm=900)
    np.testing.assert_array_equal(p.freqs_hz, freqs)


@pytest.mark.parametrize(
    ("lip", "weights", "depth", "match"),
    [
        (np.zeros((3, 2)), [0.5, 0.5], [0.0, 1.0, 2.0], "lip_hu must have shape"),
        (np.zeros((3, 2, 1)), [0.5, 0.5], [0.0, 1.0], "depths but depth_mm"),
        (np.zeros((3, 2, 1)), [0.5, 0.5, 0.0], [0.0, 1.0, 2.0], "ring_weights must have shape"),
        (np.zeros((3, 2, 1)), [0.5, 0.6], [0.0, 1.0, 2.0], "sum to 1"),
        (np.zeros((3, 2, 1)), [0.5, 0.5], [0.0, 1.0, 3.0], "uniform step"),
        (np.zeros((3, 2, 1)), [0.5, 0.5], [2.0, 1.0, 0.0], "uniform step"),
        (np.zeros((1, 2, 1)), [0.5, 0.5], [0.0], ">= 2 depths"),
        (np.full((2, 1, 1), np.nan), [1.0], [0.0, 1.0], "NaN"),
        (np.zeros((2, 1, 1)), [1.0], [0.0, np.inf], "finite depths"),
    ],
)
def test_bad_inputs_raise_model_input_error(
    lip: np.ndarray, weights: list[float], depth: list[float], match: str
) -> None:
    with pytest.raises(ModelInputError, match=match):
        build_profile(lip, weights, depth, PINE, blades=2, rpm=900)


def test_int16_input_accepted() -> None:
    lip = np.full((3, 2, 4), -600, dtype=np.int16)
    p = build_profile(lip, [0.5, 0.5], [0.0, 0.1, 0.2], PINE, blades=2, rpm=900)
    np.testing.assert_allclose(p.s0_n, 10**-1.35 * 400**0.77)


@pytest.mark.parametrize("cal", [PINE, BONE], ids=lambda c: c.name)
def test_build_profile_matches_the_force_law_on_random_lips(cal: Calibration) -> None:
    rng = np.random.default_rng(4)
    lip = rng.uniform(-1100.0, 3500.0, (30, 5, 7))
    w = rng.uniform(0.1, 1.0, 5)
    w /= w.sum()
    p = build_profile(lip, w, np.arange(30) * 0.05, cal, blades=2, rpm=900)
    g = gate(lip, cal)
    s0 = np.einsum("dra,r->d", g * a0_n(lip, 0.0, cal), w) / 7
    sk = np.einsum("kdra,r->kd", g * bk_n(lip, cal), w) / 7
    np.testing.assert_allclose(p.s0_n, s0, rtol=1e-12)
    np.testing.assert_allclose(p.sk_n, sk, rtol=1e-12)
    lo, hi = cal.c_prime_range
    cp = lip + 1000
    assert p.n_clipped == int(np.count_nonzero((g > 0) & ((cp < lo) | (cp > hi))))
    assert p.n_clipped > 0
