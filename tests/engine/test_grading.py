"""hu_grading: segment means are integral means of the lip-mean HU (closed forms)."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.engine.grading import N_HU_SEGMENTS, hu_grading, interpolant_integral


def test_a_cortical_step_has_the_integral_mean_of_its_interpolant() -> None:
    # soft bone (-433 .. a step) on a 0.05 mm grid: 200 HU up to 3.10 mm, 1700 HU from 3.15 mm,
    # the profile linear in between (as force_n and force.csv read it)
    depth = np.linspace(0.0, 10.0, 201)
    hu = np.where(depth <= 3.1 + 1e-9, 200.0, 1700.0)
    grading = hu_grading(depth, hu, 10.0)
    assert len(grading.segments) == N_HU_SEGMENTS
    seg = grading.segments[3]  # [3, 4] mm holds the step
    assert (seg.from_mm, seg.to_mm) == (3.0, 4.0)
    # closed form: 0.10 mm at 200, the 0.05 mm ramp at its mean 950, 0.85 mm at 1700
    want = (0.10 * 200.0 + 0.05 * 950.0 + 0.85 * 1700.0) / 1.0
    assert seg.mean_hu == pytest.approx(want, abs=0.005)
    # a plain mean of 33 samples is not it (the seam this replaced)
    sampled = float(np.mean(np.interp(np.linspace(3.0, 4.0, 33), depth, hu)))
    assert abs(sampled - want) > 5.0
    assert seg.misch == "D1"
    assert grading.segments[0].mean_hu == 200.0 and grading.segments[9].mean_hu == 1700.0


def test_the_integral_is_exact_for_any_piecewise_linear_profile() -> None:
    rng = np.random.default_rng(3)
    depth = np.cumsum(np.r_[0.0, rng.uniform(0.01, 0.2, 60)])
    values = rng.uniform(-1000.0, 2000.0, depth.size)
    x = np.sort(rng.uniform(0.0, depth[-1], 40))
    got = interpolant_integral(depth, values, x)
    # reference: trapezoid on the grid refined with the points themselves (exact for a
    # piecewise-linear function whose breakpoints are all included)
    for xi, gi in zip(x, got, strict=True):
        grid = np.r_[depth[depth < xi], xi]
        ref = np.trapezoid(np.interp(grid, depth, values), grid)
        assert gi == pytest.approx(ref, rel=1e-12, abs=1e-9)


def test_a_stop_at_the_entry_has_no_segment_means() -> None:
    depth = np.linspace(0.0, 2.0, 41)
    grading = hu_grading(depth, np.full(depth.size, 500.0), 0.0)
    assert all(s.mean_hu is None and s.misch is None for s in grading.segments)
    assert grading.misch_share["D3"] == 1.0
