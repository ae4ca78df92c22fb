"""Clearance to the swept drill solid (vs dense sampling) and the exact maximum safe depth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ctdrill.imaging.plan.distance import segment_solid_distance_mm, solid_distance_mm
from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark, PointLandmark
from ctdrill.imaging.plan.safety import (
    clearance_mm,
    clearance_profile_mm,
    max_safe_depth_mm,
    nearest_landmark,
)
from ctdrill.imaging.plan.types import DrillSpec, Plan

R, LT = 1.0, 0.6


def _frame(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e1 = np.cross(direction, [1.0, 0.0, 0.0])
    if np.linalg.norm(e1) < 0.1:
        e1 = np.cross(direction, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(direction, e1)


def _solid_surface(
    entry: np.ndarray, u: np.ndarray, x: float, s_min: float, step: float
) -> np.ndarray:
    """Dense points on the solid's surface (cylinder from s_min to x - LT, cone, far cap)."""
    e1, e2 = _frame(u)
    n_theta = math.ceil(2 * math.pi * R / step)
    theta = np.linspace(0.0, 2 * math.pi, n_theta, endpoint=False)
    ring = np.cos(theta)[:, None] * e1 + np.sin(theta)[:, None] * e2  # (T, 3)
    s_cyl = np.arange(s_min, x - LT, step)
    cyl = entry + s_cyl[:, None, None] * u + R * ring[None, :, :]
    n_cone = math.ceil(math.hypot(R, LT) / step) + 1
    t = np.linspace(0.0, 1.0, n_cone)  # corner -> tip
    s_cone = x - LT + t * LT
    r_cone = R * (1.0 - t)
    cone = entry + s_cone[:, None, None] * u + r_cone[:, None, None] * ring[None, :, :]
    return np.concatenate([cyl.reshape(-1, 3), cone.reshape(-1, 3)])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_point_and_segment_distance_match_dense_sampling(seed: int) -> None:
    rng = np.random.default_rng(seed)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    entry = rng.uniform(-20, 20, size=3)
    x = float(rng.uniform(3.0, 8.0))
    surface = cKDTree(_solid_surface(entry, u, x, s_min=-25.0, step=0.02))
    e1, e2 = _frame(u)
    checked = 0
    for _ in range(40):
        # Segments near the tip and the corner, where every feature of the solid matters.
        a = (
            entry
            + rng.uniform(x - 3, x + 2) * u
            + rng.uniform(-3, 3) * e1
            + rng.uniform(-3, 3) * e2
        )
        b = a + rng.normal(size=3) * 1.5
        exact = segment_solid_distance_mm(
            a[None],
            b[None],
            np.array([x]),
            entry_lps=entry,
            direction=u,
            radius_mm=R,
            tip_length_mm=LT,
        )[0]
        if exact < 0.05:
            continue  # the segment enters the solid: its surface distance is not the distance
        n = int(np.linalg.norm(b - a) / 0.01) + 2
        seg = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
        brute = surface.query(seg)[0].min()
        assert exact <= brute + 1e-9
        assert brute - exact <= 0.01
        s = (seg - entry) @ u
        rho = np.linalg.norm(seg - entry - s[:, None] * u, axis=1)
        pts = solid_distance_mm(s, rho, x, radius_mm=R, tip_length_mm=LT)
        np.testing.assert_allclose(pts, surface.query(seg)[0], atol=0.01)
        checked += 1
    assert checked >= 15


def test_inside_the_solid_is_zero_and_ahead_of_the_tip_is_tip_distance() -> None:
    s = np.array([-100.0, 4.0, 4.69, 5.0, 7.0, 4.0])
    rho = np.array([0.99, 0.0, 0.5, 0.0, 0.0, 3.0])
    d = solid_distance_mm(s, rho, 5.0, radius_mm=R, tip_length_mm=LT)
    np.testing.assert_allclose(d[:4], 0.0)
    assert d[4] == pytest.approx(2.0)
    assert d[5] == pytest.approx(2.0)  # beside the cylinder: rho - R


def _plan(landmarks: tuple[CanalLandmark | PointLandmark | MaskLandmark, ...]) -> Plan:
    return Plan(
        entry_lps=np.array([5.0, -3.0, 40.0]),
        target_lps=np.array([5.0, -3.0, 20.0]),  # straight down (-S), planned depth 20 mm
        drill=DrillSpec(diameter_mm=2 * R, tip_length_mm=LT),
        margin_mm=2.0,
        landmarks=landmarks,
    )


def test_max_safe_depth_is_exact_for_a_canal_across_the_axis() -> None:
    # Canal crossing the axis at depth 15 mm, radius 1.2: the tip reaches clearance 2 mm at
    # x = 15 - 1.2 - 2 = 11.8 mm.
    canal = CanalLandmark("canal", [[-10.0, -3.0, 25.0], [20.0, -3.0, 25.0]], radius_mm=1.2)
    plan = _plan((canal,))
    assert max_safe_depth_mm(plan) == pytest.approx(11.8, abs=1e-3)
    assert max_safe_depth_mm(plan) <= 11.8
    depth = np.array([0.0, 5.0, 11.8, 13.8, 20.0])
    np.testing.assert_allclose(
        clearance_profile_mm(plan, depth_mm=depth)[:, 0], [13.8, 8.8, 2.0, 0.0, -1.2], atol=1e-9
    )


def test_max_safe_depth_is_exact_when_the_cone_side_touches_first() -> None:
    # Canal perpendicular to the axis, passing 2.5 mm beside it at depth 10 mm. The cone's
    # side line R*s + LT*rho = R*x reaches distance q = radius + margin at
    # x = c + (LT*h - q*sqrt(R^2 + LT^2)) / R (its foot lies on the cone, checked below).
    c, h, radius, margin = 10.0, 2.5, 1.2, 2.0
    q = radius + margin
    expected = c + (LT * h - q * math.hypot(R, LT)) / R
    canal = CanalLandmark(
        "canal", [[5.0 + h, -20.0, 40.0 - c], [5.0 + h, 20.0, 40.0 - c]], radius_mm=radius
    )
    plan = _plan((canal,))
    got = max_safe_depth_mm(plan, tol_mm=1e-4)
    assert got == pytest.approx(expected, abs=1e-4)
    # foot of the perpendicular from (c, h) on the cone segment at that depth
    corner = np.array([expected - LT, R])
    along = np.array([LT, -R]) / math.hypot(R, LT)
    t = float((np.array([c, h]) - corner) @ along) / math.hypot(R, LT)
    assert 0.0 < t < 1.0
    assert clearance_mm(plan, canal, expected) == pytest.approx(margin, abs=1e-9)


def test_per_landmark_margin_and_nearest_landmark() -> None:
    canal = CanalLandmark("canal", [[-10.0, -3.0, 25.0], [20.0, -3.0, 25.0]], radius_mm=1.2)
    apex = PointLandmark("apex", [5.0, -3.0, 30.0], margin_mm=0.5)  # on the axis at 10 mm
    plan = _plan((canal, apex))
    assert max_safe_depth_mm(plan) == pytest.approx(9.5, abs=1e-3)
    depth = np.linspace(0, 20, 41)
    prof = clearance_profile_mm(plan, depth_mm=depth)
    assert prof.shape == (41, 2)
    assert np.all(np.diff(prof, axis=0) <= 1e-12)  # non-increasing in depth
    assert nearest_landmark(prof, np.array([2.0, 0.5])) == 0
    assert max_safe_depth_mm(_plan(())) == pytest.approx(30.0)
    assert max_safe_depth_mm(_plan((canal,)), limit_mm=5.0) == 5.0
    too_close = PointLandmark("touching", [5.0, -3.0, 41.0])  # 1 mm above the entry
    assert max_safe_depth_mm(_plan((too_close,))) == 0.0


def test_mask_landmark_clearance_equals_its_boundary_voxel_points() -> None:
    mask = np.zeros((6, 7, 8), dtype=bool)
    mask[2:5, 2:5, 3:6] = True  # a 3x3x3 block: 26 boundary voxels, one interior
    affine = np.array(
        [[0.5, 0.0, 0.0, 3.0], [0.0, 0.5, 0.0, -4.0], [0.0, 0.0, -1.0, 28.0], [0, 0, 0, 1.0]]
    )
    lm = MaskLandmark("block", mask, affine_lps=affine)
    pts = lm.surface_points_lps()
    assert pts.shape == (26, 3)
    plan = _plan((lm,))
    depth = np.linspace(0.0, 20.0, 21)
    got = clearance_profile_mm(plan, depth_mm=depth)[:, 0]
    as_points = tuple(PointLandmark(f"p{i}", p) for i, p in enumerate(pts))
    want = clearance_profile_mm(plan, as_points, depth).min(axis=1)
    np.testing.assert_allclose(got, want, atol=1e-12)
    # The block's top face is at z = 28 - 2 = 26 (k = 2), i.e. 14 mm below the entry.
    assert got[0] == pytest.approx(14.0)


def test_pruned_polyline_equals_the_minimum_over_its_segments() -> None:
    rng = np.random.default_rng(5)
    pts = np.cumsum(rng.normal(size=(31, 3)), axis=0) + np.array([5.0, -3.0, 30.0])
    entry, u = np.array([5.0, -3.0, 40.0]), np.array([0.0, 0.0, -1.0])
    depth = np.linspace(0.0, 20.0, 41)
    kw = {"entry_lps": entry, "direction": u, "radius_mm": R, "tip_length_mm": LT}
    union = segment_solid_distance_mm(pts[:-1], pts[1:], depth, **kw)
    singles = np.stack(
        [
            segment_solid_distance_mm(pts[i : i + 1], pts[i + 1 : i + 2], depth, **kw)
            for i in range(30)
        ]
    )
    np.testing.assert_allclose(union, singles.min(axis=0), atol=1e-12)


def test_bracket_hint_gives_the_same_safe_depth_and_bad_hints_are_ignored() -> None:
    canal = CanalLandmark("canal", [[-10.0, -3.0, 25.0], [20.0, -3.0, 25.0]], radius_mm=1.2)
    plan = _plan((canal,))
    assert max_safe_depth_mm(plan, bracket_mm=(11.75, 11.85)) == pytest.approx(11.8, abs=1e-3)
    assert max_safe_depth_mm(plan, bracket_mm=(12.0, 13.0)) == pytest.approx(11.8, abs=1e-3)
    assert max_safe_depth_mm(plan, bracket_mm=(5.0, 6.0)) == pytest.approx(11.8, abs=1e-3)
    assert max_safe_depth_mm(plan, bracket_mm=(11.0, 5.0)) == pytest.approx(11.8, abs=1e-3)
