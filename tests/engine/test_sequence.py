"""Drill sequences on a uniform slab: the annulus force in closed form (issue 18).

The model (DESIGN.md 1.4): ``F(x) = (1/R) int_0^R mean_theta f(HU(r, theta, xi(r))) dr`` with
the lip element at radius ``r`` at depth ``xi = x - l_t r / R``. A drill following a narrower
one cuts nothing where its lip is inside the earlier hole (radius ``r_p``, tip length ``l_p``,
reached depth ``d``: the points with ``r < r_p`` and ``xi < d - l_p r / r_p``). The weighting
is uniform in ``r`` (``dr``, not ``r dr``), so in material the whole lip lies in, the force is
the full-lip force times the cut share

``share(x) = 1 - |{r in [0, r_p): x - a r < d - b r}| / R``,  ``a = l_t / R``, ``b = l_p / r_p``:

- ``a == b`` (equal point angles): ``1 - r_p / R`` above ``d``, 1 below;
- ``b > a`` (a blunter follower): the hole holds ``[0, clip((d - x) / (b - a), 0, r_p))``;
- ``b < a`` (a sharper follower): it holds ``(clip((x - d) / (a - b), 0, r_p), r_p)``.

These are written out here from the geometry, not taken from the code.
"""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.engine.path import plan_path
from ctdrill.engine.sequence import drill_path, plan_sequence
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.imaging.sampling.annulus import Hole
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from ctdrill.model.calibration import load_calibration

DZ = 0.01
Z0 = -2.005  # slice centres at odd multiples of DZ/2: the slab top (z = 1) falls between two
N_SLICES = 1500
TOP_MM, SLAB_HU = 1.0, 800.0
CAL = load_calibration("bone-illustrative")
#: f(800 HU) of bone-illustrative: gate 1 (800 > 150 + 25), A0 = 10^b0 C'^n, C' = 1800
A0_800 = 10**-5.9535 * (SLAB_HU + 1000.0) ** 2.0
PILOT = DrillSpec(diameter_mm=2.0, tip_length_mm=0.6)


@pytest.fixture(scope="module")
def slab() -> CTVolume:
    z = Z0 + DZ * np.arange(N_SLICES)
    hu = np.where(z >= TOP_MM, SLAB_HU, -1000.0)
    vol = np.broadcast_to(hu[:, None, None], (N_SLICES, 11, 11)).astype(np.int16)
    affine = np.array(
        [[1.0, 0.0, 0.0, -5.0], [0.0, 1.0, 0.0, -5.0], [0.0, 0.0, DZ, Z0], [0.0, 0.0, 0.0, 1.0]]
    )
    return CTVolume(
        hu=vol,
        affine_lps=affine,
        valid=None,
        info=SeriesInfo(series_uid="1.2.3", is_hu=True),
        slice_positions_mm=np.empty(0),
    )


def _plan(drills: tuple[DrillSpec, ...], depth_mm: float = 10.0, **kw: object) -> Plan:
    base = Plan(
        entry_lps=[0.0, 0.0, 0.0],
        target_lps=[0.0, 0.0, depth_mm],
        calibration=CAL.name,
        name="seq",
        **kw,  # type: ignore[arg-type]
    )
    return base.with_drills(drills)


def _share(
    x: np.ndarray, radius: float, a: float, holes: list[tuple[float, float, float]]
) -> np.ndarray:
    """Closed-form cut share for holes (r_p, b, d) that nest (each wider hole inside the
    narrower ones' radii is handled by taking, per radius, whether any hole holds it: done on
    the hole intervals, which are [lo, hi) per the module docstring, merged by hand)."""
    held = []
    for r_p, b, d in holes:
        if b > a:
            lo, hi = np.zeros_like(x), np.clip((d - x) / (b - a), 0.0, r_p)
        elif b == a:
            lo, hi = np.zeros_like(x), np.where(x <= d, r_p, 0.0)
        else:
            lo, hi = np.clip((x - d) / (a - b), 0.0, r_p), np.full_like(x, r_p)
        held.append((lo, hi))
    # union length of the intervals, per depth (two at most here: sort and merge)
    out = np.empty_like(x)
    for i in range(x.size):
        spans = sorted((lo[i], hi[i]) for lo, hi in held if hi[i] > lo[i])
        total, end = 0.0, -1.0
        for lo_i, hi_i in spans:
            lo_i = max(lo_i, end)
            if hi_i > lo_i:
                total += hi_i - lo_i
                end = hi_i
        out[i] = 1.0 - total / radius
    return out


def _immersed(x: np.ndarray, tip_mm: float) -> np.ndarray:
    """Depths whose whole lip lies in the slab (past the trilinear ramp at its top)."""
    return x - tip_mm >= TOP_MM + DZ


def test_equal_point_angles_annulus_above_the_hole_full_lip_below(slab: CTVolume) -> None:
    drill = DrillSpec(diameter_mm=2.8, tip_length_mm=0.84)  # l/R = 0.6, as the pilot's
    plan = _plan((PILOT, drill))
    res = drill_path(slab, plan, 1, CAL, [6.0])
    x, prof = res.depth_mm, res.profile
    share = 1.0 - 1.0 / 1.4  # 0.2857...: the annulus [1.0, 1.4] of the lip [0, 1.4]
    above = _immersed(x, 0.84) & (x < 6.0 - 1e-9)
    below = x > 6.0 + 1e-9
    assert above.sum() > 50 and below.sum() > 50
    np.testing.assert_allclose(prof.s0_n[above], A0_800 * share, rtol=1e-9)
    np.testing.assert_allclose(prof.s0_n[below], A0_800, rtol=1e-9)
    np.testing.assert_allclose(prof.s_t[above], share, rtol=1e-9)
    np.testing.assert_allclose(prof.hu_mean[_immersed(x, 0.84)], SLAB_HU, rtol=1e-9)
    # the harmonics scale the same way (Bk share the lip integral)
    full = plan_path(slab, plan.for_drill(1), CAL).profile
    np.testing.assert_allclose(prof.sk_n[:, above], full.sk_n[:, above] * share, rtol=1e-9)
    assert res.inner_holes == (Hole(1.0, 0.6, 6.0),)
    # the stop and clearance are the drill's own (no landmark: the planned depth)
    assert res.stop_depth_mm == pytest.approx(10.0) and res.stop_reason == "planned_depth"


@pytest.mark.parametrize("tip_mm", [0.42, 1.26, 0.0])  # blunter, sharper, flat follower
def test_unequal_point_angles_follow_the_pilot_cone(slab: CTVolume, tip_mm: float) -> None:
    drill = DrillSpec(diameter_mm=2.8, tip_length_mm=tip_mm)
    res = drill_path(slab, _plan((PILOT, drill)), 1, CAL, [6.0])
    x, prof = res.depth_mm, res.profile
    share = _share(x, 1.4, tip_mm / 1.4, [(1.0, 0.6, 6.0)])
    ok = _immersed(x, max(tip_mm, 0.6))
    assert np.ptp(share[ok]) > 0.5  # the cone's transition is inside the tested depths
    np.testing.assert_allclose(prof.s0_n[ok], A0_800 * share[ok], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(prof.s_t[ok], share[ok], rtol=1e-9, atol=1e-12)


def test_three_drills_union_of_two_holes(slab: CTVolume) -> None:
    """Pilot reached 8 mm, the 2.8 mm drill only 5 mm: the 3.5 mm drill cuts the annulus
    outside 1.4 mm down to 5 mm, outside 1.0 mm down to 8 mm, the full lip below."""
    d2, d3 = DrillSpec(2.8, 0.84), DrillSpec(3.5, 1.05)
    res = drill_path(slab, _plan((PILOT, d2, d3)), 2, CAL, [8.0, 5.0])
    x, prof = res.depth_mm, res.profile
    want = np.where(x < 5.0, 1 - 1.4 / 1.75, np.where(x < 8.0, 1 - 1.0 / 1.75, 1.0))
    ok = _immersed(x, 1.05) & (np.abs(x - 5.0) > 1e-9) & (np.abs(x - 8.0) > 1e-9)
    np.testing.assert_allclose(prof.s0_n[ok], A0_800 * want[ok], rtol=1e-9)
    np.testing.assert_allclose(
        want[ok], _share(x, 1.75, 0.6, [(1.0, 0.6, 8.0), (1.4, 0.6, 5.0)])[ok]
    )


def test_partial_immersion_error_is_within_half_a_ring(slab: CTVolume) -> None:
    """Where the lip crosses the slab top the cut set holds a step: the midpoint rule on it is
    off by at most half a ring's weight (|C| / (2 n R)) per step, plus the trilinear ramp of
    one slice (DZ / l_t of the lip)."""
    drill = DrillSpec(diameter_mm=2.8, tip_length_mm=0.84)
    n = 6
    res = drill_path(slab, _plan((PILOT, drill)), 1, CAL, [6.0], n_rings=n, n_angles=4)
    x, prof = res.depth_mm, res.profile
    a = 0.6
    # exact: the annulus [1.0, 1.4] cuts where xi = x - a r >= TOP, i.e. r <= (x - TOP) / a
    reach = np.clip((x - TOP_MM) / a, 1.0, 1.4)
    exact = (reach - 1.0) / 1.4
    band = (x > TOP_MM) & (x < TOP_MM + 0.84 + 0.1)
    err = np.abs(prof.s_t[band] - exact[band])
    bound = (0.4 / 1.4) / (2 * n) + DZ / 0.84
    assert err.max() <= bound
    assert err.max() > 1e-3  # the staircase is there: the test can see it


def test_single_drill_sequence_is_plan_path_exactly(slab: CTVolume) -> None:
    plan = _plan((PILOT,))
    seq = plan_sequence(slab, plan, CAL)
    ref = plan_path(slab, plan, CAL)
    assert len(seq.steps) == 1 and seq.final.inner_holes == ()
    np.testing.assert_array_equal(seq.final.profile.s0_n, ref.profile.s0_n)
    np.testing.assert_array_equal(seq.final.profile.sk_n, ref.profile.sk_n)
    np.testing.assert_array_equal(seq.final.lip.hu, ref.lip.hu)


def test_each_drill_has_its_own_stop_and_the_next_cuts_to_it(slab: CTVolume) -> None:
    """A canal parallel to the axis 4 mm off it, from 6 mm down: the 2.0 mm pilot keeps the
    2 mm margin (4 - 1 - 0.5 = 2.5), the 3.6 mm drill does not (4 - 1.8 - 0.5 = 1.7): it stops
    where its solid comes within 2 mm of the canal's top end; the pilot reaches the plan."""
    canal = CanalLandmark("canal", [[4.0, 0.0, 6.0], [4.0, 0.0, 11.0]], radius_mm=0.5)
    final = DrillSpec(diameter_mm=3.6, tip_length_mm=1.08)
    plan = _plan((PILOT, final), depth_mm=9.0, landmarks=(canal,))
    seq = plan_sequence(slab, plan, CAL)
    pilot, last = seq.steps
    assert pilot.stop_reason == "planned_depth" and pilot.stop_depth_mm == pytest.approx(9.0)
    assert last.stop_reason == "margin" and last.stop_depth_mm < 9.0
    assert last.min_clearance_mm == pytest.approx(2.0, abs=1e-3)
    assert last.inner_holes == (Hole(1.0, 0.6, pilot.stop_depth_mm),)
    assert last.plan.drill == final and last.plan.drills == (final,)
    # the final drill never gets below the pilot: its whole profile is the annulus share
    x = last.depth_mm
    ok = _immersed(x, 1.08)
    np.testing.assert_allclose(last.profile.s0_n[ok], A0_800 * (1 - 1.0 / 1.8), rtol=1e-9)


def test_a_hole_bottom_between_grid_depths_never_leaks_into_the_hole(slab: CTVolume) -> None:
    """The pilot stops at 6.02 mm, between the grid depths 6.00 and 6.05: the follower's force
    (linear between grid depths, as the device and force.csv use it) is the annulus force at
    every depth down to 6.02 and, here, down to 6.05 (the hole's grid placement); the full lip
    is reached at 6.10: at most two steps late, never early."""
    from ctdrill.model.profile import force_n

    drill = DrillSpec(diameter_mm=2.8, tip_length_mm=0.84)
    res = drill_path(slab, _plan((PILOT, drill)), 1, CAL, [6.02])
    prof = res.profile
    share = 1.0 - 1.0 / 1.4
    for x in np.linspace(2.0, 6.02, 403):
        assert force_n(prof, float(x), 0.0, np.nan) == pytest.approx(A0_800 * share, rel=1e-9)
    assert force_n(prof, 6.05, 0.0, np.nan) == pytest.approx(A0_800 * share, rel=1e-9)
    assert force_n(prof, 6.10, 0.0, np.nan) == pytest.approx(A0_800, rel=1e-9)
    assert res.inner_holes == (Hole(1.0, 0.6, 6.02),)  # the true hole is reported
    # a follower stopping where the pilot stopped feels only the annulus at its stop
    same = drill_path(slab, _plan((PILOT, drill), depth_mm=6.02), 1, CAL, [6.02])
    assert same.stop_depth_mm == pytest.approx(6.02)
    got = force_n(same.profile, same.stop_depth_mm, 0.0, np.nan)
    assert got == pytest.approx(A0_800 * share, rel=1e-9)
