"""The force band: first-order propagation against the analytic derivative and a Monte Carlo."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ctdrill.model import load_calibration
from ctdrill.model.band import HuUncertainty, force_band, lip_sensitivity
from ctdrill.model.calibration import Calibration, PowerLaw
from ctdrill.model.calibration_cov import ParameterCovariance
from ctdrill.model.errors import ModelInputError
from ctdrill.model.force import slab_force_n
from ctdrill.model.profile import build_profile

CAL = load_calibration("bone-literature")
LN10 = math.log(10.0)
N_RINGS, N_ANGLES = 8, 4
WEIGHTS = np.full(N_RINGS, 1.0 / N_RINGS)


def _slab_lip(hu: float, rings_in: int) -> np.ndarray:
    """One depth of a lip whose first ``rings_in`` rings (from the tip) are in the slab."""
    lip = np.full((1, N_RINGS, N_ANGLES), -1000.0)
    lip[0, :rings_in, :] = hu
    return lip


def _with_cov(cal: Calibration, scale: float) -> Calibration:
    cov = cal.covariance
    assert cov is not None
    m = cov.array() * scale
    return replace(cal, covariance=ParameterCovariance(cov.parameters, tuple(map(tuple, m))))


def test_matches_the_analytic_derivative_of_the_slab_force() -> None:
    hu, feed = 900.0, 0.4
    band = force_band(lip_sensitivity(_slab_lip(hu, N_RINGS), WEIGHTS, CAL), CAL, feed)
    assert band is not None
    cp, ke = hu + 1000.0, CAL.ke_per_mm_s
    j = np.array([LN10, math.log(cp), feed / (1.0 + ke * feed)])  # d ln(A0 (1 + Ke v))
    assert CAL.covariance is not None
    expected = math.sqrt(j @ CAL.covariance.array() @ j)
    assert band.sd_log[0] == pytest.approx(expected, rel=1e-12)
    mean = 10 ** (CAL.a0.b0 + CAL.a0.n * math.log10(cp)) * (1 + ke * feed)
    assert band.mean_n[0] == pytest.approx(mean, rel=1e-12)
    assert band.lo_n[0] == pytest.approx(mean * math.exp(-expected), rel=1e-12)
    assert band.hi_n[0] == pytest.approx(mean * math.exp(expected), rel=1e-12)
    # the HU part: d ln A0 / d HU = n / C' inside the range, a shared offset of sigma
    hu_unc = HuUncertainty.offset(40.0, "test")
    with_hu = force_band(lip_sensitivity(_slab_lip(hu, N_RINGS), WEIGHTS, CAL), CAL, feed, hu_unc)
    assert with_hu is not None
    assert with_hu.sd_log_hu[0] == pytest.approx(CAL.a0.n * 40.0 / cp, rel=1e-12)
    assert with_hu.sd_log[0] == pytest.approx(math.hypot(expected, CAL.a0.n * 40.0 / cp))


def test_hu_part_is_the_numerical_derivative_across_the_gate() -> None:
    # a lip of mixed material, some samples on the gate's ramp: d ln S0 / d HU for an offset
    # e0 and a slope e1 (dHU = e0 + e1 HU) by central differences of the profile builder
    rng = np.random.default_rng(3)
    lip = rng.uniform(100.0, 1800.0, size=(5, N_RINGS, N_ANGLES))
    lip[:, 0, :2] = 140.0  # on the ramp (125..175)
    sens = lip_sensitivity(lip, WEIGHTS, CAL)

    def s0(e0: float, e1: float) -> np.ndarray:
        shifted = lip + e0 + e1 * lip
        return build_profile(shifted, WEIGHTS, np.arange(5) * 0.1, CAL, blades=2, rpm=900).s0_n

    h = 1e-3
    d0 = (s0(h, 0) - s0(-h, 0)) / (2 * h)
    d1 = (s0(0, h * 1e-3) - s0(0, -h * 1e-3)) / (2 * h * 1e-3)
    np.testing.assert_allclose(sens.d0_n_per_hu, d0, rtol=1e-6)
    np.testing.assert_allclose(sens.d1_n, d1, rtol=1e-6)
    np.testing.assert_allclose(sens.s0_n, s0(0, 0), rtol=1e-12)


@pytest.mark.parametrize(
    ("feed", "scale", "rings_in"),
    [(0.0, 1.0, 8), (0.0, 1.0, 3), (0.4, 1.0 / 25.0, 8), (0.4, 1.0 / 25.0, 5)],
)
def test_matches_a_monte_carlo_on_the_parameters(feed: float, scale: float, rings_in: int) -> None:
    # At zero feed ln M is linear in b0 and n: the band is exact for the full covariance. With
    # the feed the Ke term is not, so the check there is at a covariance where first order holds.
    cal = _with_cov(CAL, scale)
    hu, lt = 1100.0, 0.6
    band = force_band(lip_sensitivity(_slab_lip(hu, rings_in), WEIGHTS, cal), cal, feed)
    assert band is not None
    assert cal.covariance is not None
    rng = np.random.default_rng(11)
    draws = rng.multivariate_normal(
        [cal.a0.b0, cal.a0.n, cal.ke_per_mm_s], cal.covariance.array(), 20_000
    )
    x = rings_in / N_RINGS * lt  # the slab's contact phase: s_t = x / l_t = rings_in / rings

    def slab(b0: float, n: float, ke: float) -> float:
        law = replace(cal, a0=PowerLaw(b0, n), ke_per_mm_s=ke, harmonics=())
        kw = {"thickness_mm": 5.0, "tip_length_mm": lt, "freqs_hz": []}
        return float(slab_force_n(x, hu, feed, 0.0, law, **kw))  # type: ignore[arg-type]

    # Eq. 2-4 x Eq. 19 without vibration, vectorised over the draws; checked against the
    # model's slab_force_n on a few of them
    b0, n, ke = draws.T
    forces = rings_in / N_RINGS * 10 ** (b0 + n * math.log10(hu + 1000.0)) * (1 + ke * feed)
    for i in range(5):
        assert forces[i] == pytest.approx(slab(*draws[i]), rel=1e-12)
    lo, hi = np.percentile(forces, [15.865, 84.135])
    assert band.lo_n[0] == pytest.approx(lo, rel=0.02)
    assert band.hi_n[0] == pytest.approx(hi, rel=0.02)


def test_no_covariance_no_band_and_nothing_cut_gives_zero() -> None:
    ill = load_calibration("bone-illustrative")
    sens = lip_sensitivity(_slab_lip(900.0, N_RINGS), WEIGHTS, ill)
    assert force_band(sens, ill, 0.4, HuUncertainty.offset(30.0, "x")) is None
    air = force_band(lip_sensitivity(_slab_lip(0.0, N_RINGS), WEIGHTS, CAL), CAL, 0.4)
    assert air is not None and air.mean_n[0] == air.lo_n[0] == air.hi_n[0] == 0.0


def test_hu_uncertainty_validation_and_sum() -> None:
    with pytest.raises(ModelInputError, match="finite number >= 0"):
        HuUncertainty.offset(-1.0, "x")
    with pytest.raises(ModelInputError, match="positive semi-definite"):
        HuUncertainty(((1.0, 2.0), (2.0, 1.0)), "x")
    both = HuUncertainty.offset(30.0, "a").plus(HuUncertainty(((0.0, 0.0), (0.0, 1e-4)), "b"))
    assert both.source == "a + b"
    assert both.sd_hu_at(1000.0) == pytest.approx(math.hypot(30.0, 10.0))


def test_per_depth_ring_weights_of_a_drill_sequence() -> None:
    # a drill following a narrower one: per-depth weights summing to the cut share; the sums
    # equal build_profile's and the band's relative width that of the full lip of that material
    rng = np.random.default_rng(5)
    lip = rng.uniform(300.0, 1600.0, size=(4, N_RINGS, N_ANGLES))
    w = np.tile(WEIGHTS, (4, 1))
    w[:, :3] = 0.0  # the inner rings lie in the earlier hole
    prof = build_profile(lip, w, np.arange(4) * 0.1, CAL, blades=2, rpm=900)
    sens = lip_sensitivity(lip, w, CAL)
    np.testing.assert_allclose(sens.s0_n, prof.s0_n, rtol=1e-12)
    band = force_band(sens, CAL, 0.4)
    assert band is not None and np.all(band.lo_n < band.mean_n) and np.all(band.mean_n < band.hi_n)
    with pytest.raises(ModelInputError, match="disagree"):
        lip_sensitivity(lip, w[:, :5], CAL)
