"""Property tests: the force law never leaves finite, bounded, non-negative territory."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ctdrill.model import (
    Calibration,
    a0_n,
    bk_n,
    build_profile,
    force_n,
    force_series_n,
    gate,
    harmonic_freqs_hz,
    load_calibration,
)
from ctdrill.model.calibration import (
    MAX_EXPONENT,
    MAX_KE_PER_MM_S,
    MAX_LAW_N,
    MIN_LAW_N,
    calibration_from_dict,
)
from ctdrill.model.errors import ModelInputError
from ctdrill.model.force import MAX_FEED_MM_S, force_density_n
from ctdrill.model.layered import layered_profile
from tests.model.lip import layered_lip_hu

SETS = [load_calibration("pine-wood-paper"), load_calibration("bone-illustrative")]
INT16 = st.integers(min_value=-32768, max_value=32767)
FEED = st.floats(allow_nan=False, allow_infinity=False)
TIME = st.floats(allow_nan=False, allow_infinity=False)


def _bound_n(cal: Calibration) -> float:
    """Largest |force| the set can give: every law at its worst end of the range."""
    lo, hi = cal.c_prime_range

    def worst(b0: float, n: float) -> float:
        return max(10 ** (b0 + n * math.log10(c)) for c in (lo, hi))

    return worst(cal.a0.b0, cal.a0.n) * (1 + cal.ke_per_mm_s * MAX_FEED_MM_S) + sum(
        worst(h.b0, h.n) for h in cal.harmonics
    )


@given(hu=INT16, feed=FEED, t=TIME, which=st.sampled_from([0, 1]))
def test_every_int16_hu_any_feed_any_time_is_finite_and_bounded(
    hu: int, feed: float, t: float, which: int
) -> None:
    cal = SETS[which]
    freqs = harmonic_freqs_hz(cal, blades=2, rpm=900)
    f = float(force_density_n(hu, feed, t, cal, freqs_hz=freqs))
    assert math.isfinite(f)
    assert abs(f) <= _bound_n(cal) * (1 + 1e-12)
    dc = float(gate(hu, cal) * a0_n(hu, feed, cal))
    assert math.isfinite(dc) and dc >= 0.0


@given(hu=hnp.arrays(np.int16, st.integers(1, 64)), which=st.sampled_from([0, 1]))
def test_gate_in_unit_interval_and_laws_finite(hu: np.ndarray, which: int) -> None:
    cal = SETS[which]
    g = gate(hu, cal)
    assert np.all((g >= 0.0) & (g <= 1.0))
    assert np.all(np.isfinite(bk_n(hu, cal))) and np.all(bk_n(hu, cal) > 0.0)


@given(h1=INT16, h2=INT16, feed=FEED, which=st.sampled_from([0, 1]))
def test_a0_monotone_non_decreasing_in_hu_for_positive_n(
    h1: int, h2: int, feed: float, which: int
) -> None:
    cal = SETS[which]
    assert cal.a0.n > 0
    lo, hi = sorted((h1, h2))
    assert float(a0_n(lo, feed, cal)) <= float(a0_n(hi, feed, cal))
    # The gated DC term (what the hand feels) is monotone too.
    assert float(gate(lo, cal) * a0_n(lo, feed, cal)) <= float(gate(hi, cal) * a0_n(hi, feed, cal))


@given(
    lip=hnp.arrays(np.int16, st.tuples(st.integers(2, 6), st.integers(1, 4), st.integers(1, 4))),
    x=st.floats(allow_nan=True, allow_infinity=True),
    feed=st.floats(allow_nan=True, allow_infinity=True),
    t=TIME,
    which=st.sampled_from([0, 1]),
)
def test_profiles_from_any_int16_lip_stay_finite(
    lip: np.ndarray, x: float, feed: float, t: float, which: int
) -> None:
    cal = SETS[which]
    d, r, _ = lip.shape
    depth = np.arange(d) * 0.1
    p = build_profile(lip, np.full(r, 1.0 / r), depth, cal, blades=2, rpm=900)
    assert np.all((p.s_t >= 0.0) & (p.s_t <= 1.0))
    assert np.all(p.s0_n >= 0.0)
    assert 0 <= p.n_clipped <= p.n_samples == lip.size
    f = force_n(p, x, feed, t)
    assert math.isfinite(f) and abs(f) <= _bound_n(cal) * (1 + 1e-9)
    series = force_series_n(p, np.array([x]), feed, np.array([t]))
    assert np.all(np.isfinite(series))
    if math.isfinite(x) and math.isfinite(feed):
        assert math.isclose(series[0], f, rel_tol=1e-12, abs_tol=1e-12)


@given(
    b0=st.floats(-400, 400),
    n=st.floats(-60, 60),
    ke=st.floats(0, MAX_KE_PER_MM_S),
    lo=st.floats(1e-3, 1e4),
    span=st.floats(1.0001, 100.0),
    hu=INT16,
    feed=FEED,
    t=TIME,
)
def test_any_accepted_calibration_is_finite_for_any_input(
    b0: float, n: float, ke: float, lo: float, span: float, hu: int, feed: float, t: float
) -> None:
    doc = {
        "name": "prop",
        "material": "m",
        "source": "hypothesis",
        "c_prime_range": [lo, lo * span],
        "gate_hu": 0,
        "gate_width_hu": 10,
        "a0": {"b0": b0, "n": n, "ke": ke},
        "harmonics": [{"order": 1, "b0": b0, "n": -n}],
    }
    try:
        cal = calibration_from_dict(doc)
    except ModelInputError:
        # Refused only because a law's exponent is out of bounds, or a law exceeds MAX_LAW_N
        # somewhere in its range, or stays below MIN_LAW_N everywhere in it.
        laws = [[b0 + s * n * math.log10(c) for c in (lo, lo * span)] for s in (1, -1)]
        too_big = max(max(ends) for ends in laws) > math.log10(MAX_LAW_N) - 1e-9
        vanishing = min(max(ends) for ends in laws) < math.log10(MIN_LAW_N) + 1e-9
        assert abs(n) > MAX_EXPONENT or too_big or vanishing
        return
    f = float(force_density_n(hu, feed, t, cal, freqs_hz=[30.0]))
    assert math.isfinite(f)


@given(
    cuts=st.lists(st.floats(0.0, 10.0), min_size=2, max_size=6, unique=True),
    hus=st.lists(INT16, min_size=5, max_size=5),
    tip=st.floats(0.05, 2.0),
    rings=st.integers(1, 64),
    which=st.sampled_from([0, 1]),
)
def test_ring_quadrature_error_is_bounded_by_half_a_bin_per_boundary(
    cuts: list[float], hus: list[int], tip: float, rings: int, which: int
) -> None:
    cal = SETS[which]
    b = np.sort(np.asarray(cuts))
    if np.min(np.diff(b)) < 1e-6:
        return
    hu_layers = np.asarray(hus[: b.shape[0] - 1], dtype=np.float64)
    depth = np.linspace(-1.0, 13.0, 57)
    exact = layered_profile(b, hu_layers, depth, cal, tip_length_mm=tip, blades=2, rpm=900)
    assert np.all((exact.s_t >= 0.0) & (exact.s_t <= 1.0 + 1e-12))
    assert np.all(np.isfinite(exact.s0_n)) and np.all(exact.s0_n >= 0.0)
    lip, w = layered_lip_hu(b, hu_layers, depth, tip_length_mm=tip, n_rings=rings)
    quad = build_profile(lip, w, depth, cal, blades=2, rpm=900)
    hu_all = np.concatenate(([-1000.0], hu_layers, [-1000.0]))
    f = gate(hu_all, cal) * a0_n(hu_all, 0.0, cal)
    bound = float(np.sum(np.abs(np.diff(f)))) / (2 * rings)
    assert np.max(np.abs(quad.s0_n - exact.s0_n)) <= bound + 1e-9
