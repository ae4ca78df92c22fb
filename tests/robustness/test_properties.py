"""Properties of the numeric path under arbitrary inputs.

* ``CTVolume.sample`` never returns NaN: any points (far outside, on padding, non-finite).
* The force law is finite and bounded for every int16 HU and any feed.
* The stop depth never exceeds the planned depth; clearance never grows with depth.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from tests.robustness.make_corpus import ROOT

ALL_INT16 = np.arange(-32768, 32768, dtype=np.int16)

coords = st.one_of(
    st.floats(-50.0, 50.0),
    st.floats(-1e12, 1e12),
    st.sampled_from([0.0, -0.5, 1e300, -1e300, 5e-324]),
)


@st.composite
def volumes(draw: st.DrawFn) -> object:
    """A small CTVolume: random int16 HU, spacing, rotation, origin and padding mask."""
    from ctdrill.imaging import CTVolume, SeriesInfo

    shape = draw(st.tuples(st.integers(1, 4), st.integers(1, 5), st.integers(1, 5)))
    hu = draw(hnp.arrays(np.int16, shape))
    spacing = draw(st.tuples(*[st.floats(0.05, 5.0)] * 3))
    angle = draw(st.floats(-np.pi, np.pi))
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    affine = np.eye(4)
    affine[:3, :3] = rot * np.asarray(spacing)
    affine[:3, 3] = draw(st.tuples(*[st.floats(-100.0, 100.0)] * 3))
    valid = draw(st.none() | hnp.arrays(np.bool_, shape))
    return CTVolume(hu=hu, affine_lps=affine, valid=valid, info=SeriesInfo(series_uid="1.2.3"))


@given(
    volume=volumes(),
    points=hnp.arrays(np.float64, st.tuples(st.integers(1, 20), st.just(3)), elements=coords),
    outside=st.sampled_from([-1000.0, 0.0, -3024.0]),
)
def test_sample_is_finite_and_outside_gets_outside_hu(
    volume: object, points: np.ndarray, outside: float
) -> None:
    from ctdrill.imaging import CTVolume

    assert isinstance(volume, CTVolume)
    # points near the grid too: index space -1..n, mapped to LPS
    near = np.stack(
        [np.linspace(-1.0, n, points.shape[0]) for n in (volume.dims[0], volume.dims[1], 1.0)],
        axis=1,
    )
    for pts in (points, volume.index_to_lps(near)):
        hu = volume.sample(pts, order=1, outside_hu=outside)
        assert hu.shape == (pts.shape[0],)
        assert np.isfinite(hu).all(), (pts, hu)
        lo = min(float(volume.hu.min()), outside)
        hi = max(float(volume.hu.max()), outside)
        assert ((hu >= lo - 1e-6) & (hu <= hi + 1e-6)).all()
        far = np.abs(pts).max(axis=1) > 1e6
        assert (hu[far] == outside).all()


@given(volume=volumes(), bad=st.sampled_from([np.nan, np.inf, -np.inf]))
def test_sample_of_nonfinite_point_is_never_nan(volume: object, bad: float) -> None:
    """A NaN/inf point is outside (outside_hu) or refused with ImagingInputError, never NaN."""
    from ctdrill.imaging import CTVolume, ImagingInputError

    assert isinstance(volume, CTVolume)
    points = np.array([[0.0, 0.0, 0.0], [bad, 0.0, 0.0]])
    try:
        hu = volume.sample(points, outside_hu=-1000.0)
    except ImagingInputError:
        return
    assert np.isfinite(hu).all()
    assert hu[1] == -1000.0


@pytest.mark.parametrize("name", ["pine-wood-paper", "bone-illustrative"])
def test_force_law_is_finite_and_bounded_for_every_int16_hu(name: str) -> None:
    from ctdrill.model import a0_n, bk_n, gate, load_calibration

    cal = load_calibration(name)
    lo, hi = cal.c_prime_range
    for feed in (-5.0, 0.0, 0.4, 10.0, 1e6):
        a0 = a0_n(ALL_INT16, feed, cal)
        assert np.isfinite(a0).all() and (a0 > 0.0).all()
        feed_max = 1.0 + cal.ke_per_mm_s * max(0.0, min(feed, 1e6))
        bound = 10.0**cal.a0.b0 * max(lo**cal.a0.n, hi**cal.a0.n) * feed_max
        assert a0.max() <= bound * (1 + 1e-9)
    bk = bk_n(ALL_INT16, cal)
    assert np.isfinite(bk).all()
    for k, h in enumerate(cal.harmonics):
        assert np.abs(bk[k]).max() <= 10.0**h.b0 * max(lo**h.n, hi**h.n) * (1 + 1e-9)
    g = gate(ALL_INT16, cal)
    assert ((g >= 0.0) & (g <= 1.0)).all()


@settings(max_examples=30)
@given(
    lip=hnp.arrays(np.int16, st.tuples(st.integers(2, 6), st.integers(1, 4), st.integers(1, 8))),
    depth_mm=st.floats(-1e9, 1e9),
    feed=st.floats(-1e9, 1e9),
    t_s=st.floats(-1e12, 1e12),
)
def test_profile_and_force_finite_for_any_int16_lip(
    lip: np.ndarray, depth_mm: float, feed: float, t_s: float
) -> None:
    from ctdrill.model import build_profile, force_n, load_calibration

    cal = load_calibration("bone-illustrative")
    weights = np.full(lip.shape[1], 1.0 / lip.shape[1])
    depth = np.arange(lip.shape[0]) * 0.05
    profile = build_profile(lip, weights, depth, cal, blades=2, rpm=900.0)
    for arr in (profile.s0_n, profile.sk_n, profile.s_t, profile.hu_mean):
        assert np.isfinite(arr).all()
    assert ((profile.s_t >= 0.0) & (profile.s_t <= 1.0)).all()
    assert (profile.s0_n >= 0.0).all()
    force = force_n(profile, depth_mm, feed, t_s)
    assert np.isfinite(force)


@cache
def demo_case() -> tuple[object, object, object]:
    """The bundled demo phantom, its plan and calibration."""
    from ctdrill.imaging import load_series
    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.model import load_calibration

    plan = load_plan(ROOT / "assets" / "demo" / "plan.json")
    return load_series(ROOT / "assets" / "demo" / "ct"), plan, load_calibration(plan.calibration)


offsets = st.tuples(*[st.floats(-4.0, 4.0)] * 3)


@settings(max_examples=25)
@given(
    entry_shift=offsets,
    target_shift=offsets,
    margin=st.floats(0.0, 6.0),
    canal_shift=offsets,
    radius=st.floats(0.0, 3.0),
)
def test_stop_depth_never_exceeds_planned_depth_and_clearance_is_monotone(
    entry_shift: tuple[float, float, float],
    target_shift: tuple[float, float, float],
    margin: float,
    canal_shift: tuple[float, float, float],
    radius: float,
) -> None:
    from ctdrill.app.errors import AppInputError
    from ctdrill.engine.path import plan_path
    from ctdrill.imaging.errors import ImagingInputError
    from ctdrill.imaging.plan.landmarks import CanalLandmark
    from ctdrill.imaging.plan.types import Plan

    volume, plan, cal = demo_case()
    assert isinstance(plan, Plan)
    entry = plan.entry_lps + np.asarray(entry_shift)
    target = plan.target_lps + np.asarray(target_shift)
    if np.linalg.norm(target - entry) < 0.5:
        return
    canal = plan.landmarks[0]
    assert isinstance(canal, CanalLandmark)
    moved = replace(canal, points_lps=canal.points_lps + np.asarray(canal_shift), radius_mm=radius)
    trial = replace(plan, entry_lps=entry, target_lps=target, margin_mm=margin, landmarks=(moved,))
    try:
        result = plan_path(volume, trial, cal)  # type: ignore[arg-type]
    except (AppInputError, ImagingInputError):  # e.g. the entry left the scan (PathInputError)
        assume(False)
        return
    assert 0.0 <= result.stop_depth_mm <= trial.planned_depth_mm + 1e-9
    assert result.stop_reason in ("planned_depth", "margin", "out_of_volume")
    clearance = result.clearance_mm[:, 0]
    assert (np.diff(clearance) <= 1e-9).all(), "clearance grew with depth"
    if result.stop_reason == "margin":
        assert result.stop_depth_mm <= result.max_safe_depth_mm + 1e-9
    stop_index = np.searchsorted(result.depth_mm, result.stop_depth_mm, side="right") - 1
    if stop_index >= 0 and clearance[0] >= margin:
        assert clearance[stop_index] >= margin - 1e-3, "stopped inside the margin"
