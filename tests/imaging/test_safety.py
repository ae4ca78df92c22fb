"""Clearance to the swept drill solid (vs dense sampling) and the exact maximum safe depth."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ctdrill.imaging.plan.distance import segment_solid_distance_mm, solid_distance_mm
from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark, PointLandmark
from ctdrill.imaging.plan.safety import (
    SEARCH_BEYOND_PLAN_MM,
    clearance_mm,
    clearance_profile_mm,
    max_safe_depth_mm,
    safe_depth,
    search_limit_mm,
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


def test_signed_distance_inside_the_solid_and_ahead_of_the_tip() -> None:
    s = np.array([-100.0, -100.0, 4.0, 5.0, 7.0, 4.0, 4.4])
    rho = np.array([0.99, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0])
    d = solid_distance_mm(s, rho, 5.0, radius_mm=R, tip_length_mm=LT)
    # inside the cylinder: rho - R; on the axis 1 mm behind the tip: the cone side is nearer,
    # at (R (x - s) - rho l_t) / sqrt(R^2 + l_t^2); the tip itself is on the surface.
    np.testing.assert_allclose(d[:4], [-0.01, -1.0, -1.0 / math.hypot(R, LT), 0.0], atol=1e-12)
    assert d[4] == pytest.approx(2.0)
    assert d[5] == pytest.approx(2.0)  # beside the cylinder: rho - R
    assert d[6] == pytest.approx(-0.6 / math.hypot(R, LT))


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
    # signed: once the centre line lies on the axis of the cylinder it is R deep inside
    np.testing.assert_allclose(
        clearance_profile_mm(plan, depth_mm=depth)[:, 0], [13.8, 8.8, 2.0, 0.0, -2.2], atol=1e-9
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


def test_per_landmark_margin_and_the_binding_landmark() -> None:
    canal = CanalLandmark("canal", [[-10.0, -3.0, 25.0], [20.0, -3.0, 25.0]], radius_mm=1.2)
    apex = PointLandmark("apex", [5.0, -3.0, 30.0], margin_mm=0.5)  # on the axis at 10 mm
    plan = _plan((canal, apex))
    got = safe_depth(plan)
    assert got.depth_mm == pytest.approx(9.5, abs=1e-3) and got.depth_mm <= 9.5
    assert got.binding == 1 and not got.capped  # the apex (margin 0.5) binds, not the canal
    # with the canal's margin 2.5 and the apex off the path, the canal binds at 15 - 1.2 - 2.5
    far = PointLandmark("far", [40.0, -3.0, 30.0], margin_mm=0.5)
    wide = CanalLandmark("canal", canal.points_lps, radius_mm=1.2, margin_mm=2.5)
    got = safe_depth(_plan((far, wide)))
    assert got.depth_mm == pytest.approx(11.3, abs=1e-3) and got.binding == 1
    depth = np.linspace(0, 20, 41)
    prof = clearance_profile_mm(plan, depth_mm=depth)
    assert prof.shape == (41, 2)
    assert np.all(np.diff(prof, axis=0) <= 1e-12)  # non-increasing in depth
    free = safe_depth(_plan(()))
    assert free == type(free)(30.0, None, True)
    assert search_limit_mm(plan) == plan.planned_depth_mm + SEARCH_BEYOND_PLAN_MM == 30.0
    assert max_safe_depth_mm(_plan((canal,)), limit_mm=5.0) == 5.0
    assert safe_depth(_plan((canal,)), limit_mm=5.0).capped
    too_close = PointLandmark("touching", [5.0, -3.0, 41.0])  # 1 mm above the entry
    assert safe_depth(_plan((too_close,))) == type(free)(0.0, 0, False)


@pytest.mark.parametrize("kind", ["canal", "point"])
def test_radius_and_margin_zero_stop_at_contact(kind: str) -> None:
    # The centre line (or point) crosses the axis at depth 15 mm: with radius 0 and margin 0
    # the tip may touch it and never pass (a distance that is never negative let it through).
    if kind == "canal":
        lm: CanalLandmark | PointLandmark = CanalLandmark(
            "thin", [[-10.0, -3.0, 25.0], [20.0, -3.0, 25.0]], radius_mm=0.0, margin_mm=0.0
        )
    else:
        lm = PointLandmark("apex", [5.0, -3.0, 25.0], margin_mm=0.0)
    plan = _plan((lm,))
    got = safe_depth(plan)
    assert got.depth_mm == pytest.approx(15.0, abs=1e-3) and got.depth_mm <= 15.0
    assert got.binding == 0
    # past contact the clearance is negative: minus the depth of the line inside the drill
    prof = clearance_profile_mm(plan, depth_mm=np.array([14.0, 15.0, 15.3, 20.0]))[:, 0]
    np.testing.assert_allclose(prof[:2], [1.0, 0.0], atol=1e-9)
    assert prof[2] == pytest.approx(-0.3 * R / math.hypot(R, LT), abs=1e-7)
    assert prof[3] == pytest.approx(-R, abs=1e-7)  # on the axis of the cylinder


def test_mask_voxels_are_boxes_measured_to_their_faces() -> None:
    mask = np.zeros((6, 7, 8), dtype=bool)
    mask[2:5, 2:5, 3:6] = True  # a 3x3x3 block around the axis
    affine = np.array(
        [[0.5, 0.0, 0.0, 3.0], [0.0, 0.5, 0.0, -4.0], [0.0, 0.0, -1.0, 28.0], [0, 0, 0, 1.0]]
    )
    lm = MaskLandmark("block", mask, affine_lps=affine)
    plan = _plan((lm,))
    depth = np.array([0.0, 10.0, 13.5, 14.0, 20.0])
    got = clearance_profile_mm(plan, depth_mm=depth)[:, 0]
    # The top face of the block is at z = 28 - 1.5 = 26.5 (k = 1.5), 13.5 mm below the entry
    # (its voxel centres at 14 mm). Half a millimetre past contact the deepest block point is
    # on the axis at the face: -(0.5 R) / sqrt(R^2 + l_t^2) from the cone; deep through it, -R.
    want = [13.5, 3.5, 0.0, -0.5 * R / math.hypot(R, LT), -R]
    np.testing.assert_allclose(got, want, atol=1e-7)
    assert max_safe_depth_mm(replace(plan, margin_mm=0.0)) == pytest.approx(13.5, abs=1e-3)


def test_mask_corner_on_the_axis_is_where_the_tip_touches() -> None:
    # One 0.5 mm voxel whose corner sits on the axis 10 mm deep, the voxel beyond it: the
    # stop for a 2 mm margin is at 8 mm (the voxel centre lies 0.43 mm further).
    mask = np.ones((1, 1, 1), dtype=bool)
    corner = np.array([5.0, -3.0, 30.0])
    affine = np.diag([0.5, 0.5, -0.5, 1.0])
    affine[:3, 3] = corner + np.array([0.25, 0.25, -0.25])  # the centre
    plan = _plan((MaskLandmark("voxel", mask, affine_lps=affine),))
    assert max_safe_depth_mm(plan) == pytest.approx(8.0, abs=1e-3)
    assert max_safe_depth_mm(plan) <= 8.0
    assert clearance_profile_mm(plan, depth_mm=np.array([8.0]))[0, 0] == pytest.approx(2.0)


def test_an_oblique_mask_grid_matches_dense_sampling_of_its_boxes() -> None:
    rng = np.random.default_rng(3)
    lin = np.array([[0.4, 0.1, 0.05], [-0.1, 0.45, 0.1], [0.05, -0.1, -0.5]])  # sheared
    affine = np.eye(4)
    affine[:3, :3] = lin
    affine[:3, 3] = [4.0, -4.0, 27.0]
    mask = rng.random((4, 5, 5)) < 0.4
    plan = _plan((MaskLandmark("blob", mask, affine_lps=affine),))
    depth = np.linspace(8.0, 16.0, 9)
    got = clearance_profile_mm(plan, depth_mm=depth)[:, 0]
    n = 11
    g = np.linspace(-0.5, 0.5, n)
    sub = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    ijk = (np.argwhere(mask)[:, ::-1][:, None, :] + sub[None]).reshape(-1, 3)
    pts = ijk @ lin.T + affine[:3, 3]
    u = plan.direction
    s = (pts - plan.entry_lps) @ u
    rho = np.linalg.norm(pts - plan.entry_lps - s[:, None] * u, axis=1)
    brute = np.array(
        [solid_distance_mm(s, rho, x, radius_mm=R, tip_length_mm=LT).min() for x in depth]
    )
    spacing = np.linalg.norm(lin, axis=0).sum() / (n - 1) / 2  # farthest from a sample
    assert np.all(got <= brute + 1e-9)  # the exact minimum is never above a sample
    assert np.all(brute - got <= spacing)
    assert got.min() < 0.0 < got.max()  # both signs were exercised


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
