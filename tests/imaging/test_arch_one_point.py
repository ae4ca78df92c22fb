"""ArchCurve.project of one point (Python floats) against the same point among many (NumPy):
the same IEEE operations in the same order, so the same bits."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.sampling.arch import ArchCurve
from tests.conftest import ASSETS


@pytest.mark.parametrize("window_mm", [10.0, 3.0, 0.0])
def test_one_point_projects_as_in_a_batch(window_mm: float) -> None:
    arch = load_plan(ASSETS / "demo" / "plan.json").arch_lps
    assert arch is not None
    curve = ArchCurve(arch, window_mm)
    pts = arch.mean(axis=0) + np.random.default_rng(0).normal(0.0, 15.0, (150, 3))
    s_all, t_all = curve.project(pts)
    one = np.array([curve.project(p[None, :]) for p in pts])[:, :, 0]
    np.testing.assert_array_equal(one[:, 0], s_all)
    np.testing.assert_array_equal(one[:, 1], t_all)
    assert np.isfinite(s_all).sum() > 100 and np.isnan(s_all).any()


@pytest.mark.parametrize("window_mm", [10.0, 3.0, 0.0])
def test_arc_of_one_and_buccal_normal_as_the_arrays_give_them(window_mm: float) -> None:
    """``arc_of_one`` is project's arc position, ``buccal_normal_xy`` the normal of
    ``frame`` signed away from the centroid: bit for bit."""
    arch = load_plan(ASSETS / "demo" / "plan.json").arch_lps
    assert arch is not None
    curve = ArchCurve(arch, window_mm)
    pts = arch.mean(axis=0) + np.random.default_rng(1).normal(0.0, 15.0, (150, 3))
    s_all, _ = curve.project(pts)
    one = [curve.arc_of_one(float(p[0]), float(p[1])) for p in pts]
    np.testing.assert_array_equal(np.array([np.nan if s is None else s for s in one]), s_all)
    for s in s_all[np.isfinite(s_all)]:
        _, _, normal = curve.frame(np.array([s]))
        point = curve.point_xy(np.array([s]))[0]
        inward = float((curve._centroid_xy - point) @ normal[0, :2])
        want = -normal[0, :2] if inward > 0.0 else normal[0, :2]
        got = curve.buccal_normal_xy(float(s))
        assert got is not None
        np.testing.assert_array_equal(got, want)
