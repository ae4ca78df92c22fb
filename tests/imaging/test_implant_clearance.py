"""Exact signed distance from the implant body to every landmark kind (closed forms, dense
sampling, a property test), and the drill's numbers left unchanged by the shared routine."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from ctdrill.imaging.plan.distance import DrillSolid, solid_distance_mm
from ctdrill.imaging.plan.implant_safety import (
    ImplantBody,
    implant_body,
    implant_clearance,
    implant_margin_warnings,
)
from ctdrill.imaging.plan.implants import ImplantSpec, load_implant_library
from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark, PointLandmark
from ctdrill.imaging.plan.revolution import hull_excess_mm
from ctdrill.imaging.plan.types import Plan

PARALLEL = ImplantSpec("parallel 4.1 x 10", 4.1, 10.0, 4.1, "flat")
ROUND = ImplantSpec("round 4.0 x 11", 4.0, 11.0, 4.0, "round")
TAPERED = ImplantSpec("tapered 4.1 x 10", 4.1, 10.0, 2.9, "round")


def _frame(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e1 = np.cross(u, [1.0, 0.0, 0.0])
    if np.linalg.norm(e1) < 0.1:
        e1 = np.cross(u, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def _vertical_plan(spec: ImplantSpec, **kw: object) -> Plan:
    """Entry at the origin, target 12 mm down (LPS -z): apex at z = -12, platform above it."""
    return Plan(entry_lps=np.zeros(3), target_lps=np.array([0.0, 0.0, -12.0]), implant=spec, **kw)


def _one(plan: Plan, landmark: object) -> float:
    body = implant_body(plan)
    assert body is not None
    return float(landmark.clearance_mm(body, np.array([body.apex_depth_mm]))[0])  # type: ignore[attr-defined]


def test_vertical_implant_beside_a_straight_canal_is_the_gap_less_both_radii() -> None:
    plan = _vertical_plan(PARALLEL)  # body from z = -2 (platform) to z = -12 (apex)
    for gap in (8.0, 4.2, 3.0, 2.05, 1.0, 0.0):
        # a canal along y, 1.2 mm radius, level with the body's middle, `gap` from the axis
        canal = CanalLandmark("ian", np.array([[gap, -30.0, -7.0], [gap, 30.0, -7.0]]), 1.2)
        # outside: the horizontal gap less both radii; crossing: as negative as it is deep
        assert _one(plan, canal) == pytest.approx(gap - 2.05 - 1.2, abs=1e-7)
    # a vertical canal parallel to the axis, running past the whole body
    canal = CanalLandmark("v", np.array([[0.0, 5.0, 10.0], [0.0, 5.0, -30.0]]), 1.0)
    assert _one(plan, canal) == pytest.approx(5.0 - 2.05 - 1.0, abs=1e-7)
    # below the flat apex: the vertical gap less the canal's radius
    below = CanalLandmark("b", np.array([[-30.0, 0.5, -15.0], [30.0, 0.5, -15.0]]), 1.0)
    assert _one(plan, below) == pytest.approx(3.0 - 1.0, abs=1e-7)


def test_tilted_implant_against_a_point_and_a_canal_parallel_to_it() -> None:
    tilt = math.radians(25.0)
    u = np.array([math.sin(tilt), 0.0, -math.cos(tilt)])
    entry = np.array([10.0, -4.0, 3.0])
    plan = Plan(entry_lps=entry, target_lps=entry + 13.0 * u, implant=PARALLEL)
    e1, e2 = _frame(u)
    # a point 3.5 mm off the axis at 6 mm below the platform (platform at depth 3)
    side = entry + 9.0 * u + 3.5 * (0.6 * e1 + 0.8 * e2)
    assert _one(plan, PointLandmark("p", side)) == pytest.approx(3.5 - 2.05, abs=1e-7)
    # a point 2 mm beyond the flat apex on the axis, and one beyond the apex's rim
    assert _one(plan, PointLandmark("a", entry + 15.0 * u)) == pytest.approx(2.0, abs=1e-7)
    rim = entry + 14.0 * u + (2.05 + 1.0) * e1
    assert _one(plan, PointLandmark("r", rim)) == pytest.approx(math.sqrt(2.0), abs=1e-7)
    # a canal parallel to the tilted axis, 6 mm from it
    canal = CanalLandmark("c", np.stack([entry - 5 * u + 6 * e2, entry + 25 * u + 6 * e2]), 1.5)
    assert _one(plan, canal) == pytest.approx(6.0 - 2.05 - 1.5, abs=1e-7)


def test_round_apex_above_a_point_and_penetration_depths() -> None:
    plan = _vertical_plan(ROUND)  # apex tip at z = -12, hemisphere centre at z = -10
    for h in (3.0, 0.5):
        assert _one(plan, PointLandmark("p", np.array([0.0, 0.0, -12.0 - h]))) == pytest.approx(
            h, abs=1e-7
        )
    # off the axis below the hemisphere's centre: the distance to the sphere
    p = np.array([1.5, 1.0, -13.5])
    expect = float(np.linalg.norm(p - [0.0, 0.0, -10.0])) - 2.0
    assert _one(plan, PointLandmark("q", p)) == pytest.approx(expect, abs=1e-7)
    # inside: minus the distance to the nearest surface
    inside = np.array([0.5, 0.0, -11.0])
    expect = -(2.0 - float(np.linalg.norm(inside - [0.0, 0.0, -10.0])))
    assert _one(plan, PointLandmark("i", inside)) == pytest.approx(expect, abs=1e-7)
    assert _one(plan, PointLandmark("m", np.array([0.0, 0.0, -5.0]))) == pytest.approx(
        -2.0, abs=1e-7
    )
    # a tapered body's round apex: straight below the tip as well
    tapered = _vertical_plan(TAPERED)
    assert _one(tapered, PointLandmark("t", np.array([0.0, 0.0, -14.0]))) == pytest.approx(
        2.0, abs=1e-7
    )


def test_a_voxel_block_beside_the_implant_on_an_oblique_grid() -> None:
    plan = _vertical_plan(PARALLEL)
    # a block of voxels whose near face is the plane x = 4, on a grid rotated about x
    c, s = math.cos(0.3), math.sin(0.3)
    lin = np.array([[0.5, 0.0, 0.0], [0.0, 0.5 * c, -0.5 * s], [0.0, 0.5 * s, 0.5 * c]])
    aff = np.eye(4)
    aff[:3, :3] = lin
    aff[:3, 3] = [4.25, -15.0, -15.0]  # voxel (0, j, k) spans x from 4.0 to 4.5
    mask = np.ones((60, 60, 6), dtype=bool)
    block = MaskLandmark("block", mask, affine_lps=aff)
    assert _one(plan, block) == pytest.approx(4.0 - 2.05, abs=1e-7)
    moved = aff.copy()
    moved[0, 3] = 1.25  # the face at x = 1: 1.05 mm deep into the body
    assert _one(plan, MaskLandmark("deep", mask, affine_lps=moved)) == pytest.approx(
        -1.05, abs=1e-7
    )


def _surface(spec: ImplantSpec, body: ImplantBody, step: float) -> np.ndarray:
    """Dense points on the body's own surface (its outline revolved, both end discs)."""
    s, r = spec.profile_mm(n=max(8, int(math.pi * spec.apex_diameter_mm / step)))
    pts_s, pts_r = [], []
    for (s0, r0), (s1, r1) in itertools.pairwise(zip(s, r, strict=True)):
        n = max(2, math.ceil(math.hypot(s1 - s0, r1 - r0) / step) + 1)
        t = np.linspace(0.0, 1.0, n)
        pts_s.append(s0 + t * (s1 - s0))
        pts_r.append(r0 + t * (r1 - r0))
    n_disc = math.ceil(spec.radius_mm / step) + 1
    pts_s.append(np.zeros(n_disc))  # the platform disc
    pts_r.append(np.linspace(0.0, spec.radius_mm, n_disc))
    ss, rr = np.concatenate(pts_s), np.concatenate(pts_r)
    n_t = math.ceil(2 * math.pi * spec.radius_mm / step)
    theta = np.linspace(0.0, 2 * math.pi, n_t, endpoint=False)
    e1, e2 = _frame(body.direction)
    ring = np.cos(theta)[:, None] * e1 + np.sin(theta)[:, None] * e2
    platform = body.entry_lps + (body.apex_depth_mm - spec.length_mm) * body.direction
    pts = platform + ss[:, None, None] * body.direction + rr[:, None, None] * ring[None]
    return pts.reshape(-1, 3)


@pytest.mark.parametrize("spec", [PARALLEL, ROUND, TAPERED], ids=lambda s: s.name)
def test_canal_clearance_matches_dense_sampling(spec: ImplantSpec) -> None:
    rng = np.random.default_rng(7)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    entry = rng.uniform(-10.0, 10.0, size=3)
    plan = Plan(entry_lps=entry, target_lps=entry + 12.0 * u, implant=spec)
    body = implant_body(plan)
    assert body is not None
    step = 0.04
    tree = cKDTree(_surface(spec, body, step))
    excess = hull_excess_mm(spec.radius_mm, spec.length_mm, spec.apex_diameter_mm / 2.0)
    e1, e2 = _frame(u)
    checked = 0
    for _ in range(16):
        a = entry + rng.uniform(0.0, 16.0) * u + rng.uniform(-5, 5) * e1 + rng.uniform(-5, 5) * e2
        b = a + rng.normal(size=3) * 2.0
        canal = CanalLandmark("c", np.stack([a, b]), radius_mm=0.0)
        exact = _one(plan, canal)
        if exact < 0.05:
            continue  # entering the body: the surface distance is not the signed distance
        line = a + np.linspace(0.0, 1.0, int(np.linalg.norm(b - a) / 0.01) + 2)[:, None] * (b - a)
        brute = float(tree.query(line)[0].min())
        assert exact <= brute + 1e-9  # a lower bound of every sampled pair
        assert brute - exact <= step + excess  # and attained within the sampling
        checked += 1
    assert checked >= 6


_SPECS = st.builds(
    lambda d, length, taper, apex: ImplantSpec(
        "x", d, length, d - taper if apex == "round" or taper < d else d, apex
    ),
    st.floats(3.0, 6.0),
    st.floats(6.0, 14.0),
    st.floats(0.0, 1.5),
    st.sampled_from(["flat", "round"]),
)


@settings(max_examples=15, deadline=None)
@given(spec=_SPECS, seed=st.integers(0, 2**31 - 1))
def test_point_distance_is_a_lower_bound_attained_within_the_sampling(
    spec: ImplantSpec, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    entry = rng.uniform(-5.0, 5.0, size=3)
    plan = Plan(entry_lps=entry, target_lps=entry + (spec.length_mm + 1.0) * u, implant=spec)
    body = implant_body(plan)
    assert body is not None
    step = 0.05
    tree = cKDTree(_surface(spec, body, step))
    excess = hull_excess_mm(spec.radius_mm, spec.length_mm, spec.apex_diameter_mm / 2.0)
    pts = body.entry_lps + rng.uniform(-4.0, spec.length_mm + 6.0, size=(40, 1)) * u
    pts = pts + rng.normal(size=(40, 3)) * 3.0
    exact = body.distance_at_placement_mm(pts)
    nearest = tree.query(pts)[0]
    s = (pts - body.entry_lps) @ u - (body.apex_depth_mm - spec.length_mm)
    rho = np.linalg.norm(pts - body.entry_lps - ((pts - body.entry_lps) @ u)[:, None] * u, axis=1)
    r_at = np.array([spec.radius_at_mm(float(v)) for v in s])
    inside = (s >= 0.0) & (s <= spec.length_mm) & (rho < r_at)
    outside = ~inside
    # outside: never above any sampled distance, and within the sampling of the nearest
    assert np.all(exact[outside] <= nearest[outside] + 1e-9)
    assert np.all(nearest[outside] - exact[outside] <= step + excess)
    # inside: minus the distance to the surface, as deep as it is
    assert np.all(exact[inside] <= 1e-9)
    np.testing.assert_allclose(-exact[inside], nearest[inside], atol=step + excess)
    # a landmark point: the same number through the landmark protocol
    k = int(np.argmin(np.abs(exact)))
    assert _one(plan, PointLandmark("p", pts[k])) == pytest.approx(float(exact[k]), abs=1e-7)


def _old_drill_distance(
    s: np.ndarray, rho: np.ndarray, x: float, r: float, lt: float
) -> np.ndarray:
    """The drill solid's closed form as ctdrill computed it before the shared routine."""
    corner = x - lt
    d_ray = np.hypot(np.maximum(s - corner, 0.0), rho - r)
    ds, dr = s - corner, rho - r
    t = np.clip((ds * lt - dr * r) / (lt**2 + r**2), 0.0, 1.0)
    d_cone = np.hypot(ds - t * lt, dr + t * r)
    inside = (s <= x) & (rho <= r) & (rho * lt <= r * (x - s))
    return np.where(inside, -np.minimum(d_ray, d_cone), np.minimum(d_ray, d_cone))


@pytest.mark.parametrize("lt", [0.6, 0.0, 1.3])
def test_the_drill_solid_keeps_its_numbers(lt: float) -> None:
    rng = np.random.default_rng(3)
    s = rng.uniform(-5.0, 15.0, 20_000)
    rho = rng.uniform(0.0, 4.0, 20_000)
    new = solid_distance_mm(s, rho, 10.0, radius_mm=1.4, tip_length_mm=lt)
    np.testing.assert_allclose(new, _old_drill_distance(s, rho, 10.0, 1.4, lt), rtol=0, atol=1e-9)
    solid = DrillSolid(np.zeros(3), np.array([0.0, 0.0, -1.0]), 1.4, lt)
    pts = np.column_stack([rho, np.zeros_like(rho), -s])
    np.testing.assert_allclose(solid.signed_distance_mm(pts, np.array(10.0)), new, atol=1e-12)


def test_binding_landmark_and_the_margin_warning() -> None:
    canal = CanalLandmark("ian", np.array([[3.8, -30.0, -11.0], [3.8, 30.0, -11.0]]), 1.2)
    point = PointLandmark("root apex", np.array([-6.0, 0.0, -5.0]), margin_mm=1.0)
    plan = _vertical_plan(PARALLEL, landmarks=(point, canal), name="36")
    result = implant_clearance(plan)
    assert result is not None
    np.testing.assert_allclose(result.clearance_mm, [6.0 - 2.05, 3.8 - 2.05 - 1.2], atol=1e-7)
    assert result.binding == 1  # the canal: 0.55 mm against its 2 mm margin
    doc = result.to_json()
    assert doc["implant_clearance_mm"] == pytest.approx(0.55, abs=1e-7)
    assert doc["implant_binding_landmark"] == {"name": "ian", "margin_mm": 2.0}
    (warning,) = implant_margin_warnings(plan, result)
    code, message = warning.code, warning.message
    assert code == "implant_violates_margin"
    assert "'ian' 0.55 mm (margin 2 mm)" in message and "root apex" not in message
    far = _vertical_plan(PARALLEL, landmarks=(point,))
    assert implant_margin_warnings(far, implant_clearance(far)) == []
    assert implant_clearance(Plan(np.zeros(3), np.array([0, 0, -9.0]), landmarks=(point,))) is None


def test_the_library_round_apexes_are_within_a_hundredth_of_their_hull() -> None:
    excess = [
        hull_excess_mm(s.radius_mm, s.length_mm, s.apex_diameter_mm / 2.0)
        for s in load_implant_library()
        if s.apex == "round"
    ]
    assert 0.0 < max(excess) < 0.01


@pytest.mark.parametrize("seed", range(6))
def test_mask_clearance_is_the_minimum_over_its_voxels(seed: int) -> None:
    """The voxel-union reduction holds for the implant body: against the body's signed
    distance sampled on a lattice inside every labelled voxel (sheared grid, masks beside and
    across the body)."""
    rng = np.random.default_rng(seed)
    spec = [PARALLEL, ROUND, TAPERED][seed % 3]
    plan = _vertical_plan(spec)
    body = implant_body(plan)
    assert body is not None
    x0 = rng.uniform(-1.0, 2.0) if seed < 3 else rng.uniform(2.5, 4.0)  # across / beside
    lin = np.diag([0.6, 0.5, 0.7]) + rng.uniform(-0.15, 0.15, size=(3, 3))
    aff = np.eye(4)
    aff[:3, :3] = lin
    aff[:3, 3] = [x0, rng.uniform(-2.0, 0.0), -9.0 - 3.0 * (seed == 4)]
    mask = rng.random((6, 6, 6)) < 0.3
    lm = MaskLandmark("m", mask, affine_lps=aff)
    exact = _one(plan, lm)
    assert (exact < 0.0) == (seed < 3)
    g = (np.arange(9) / 8.0) - 0.5
    cube = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    kji = np.argwhere(mask)
    idx = (kji[:, ::-1][:, None, :] + cube[None, :, :]).reshape(-1, 3)
    sampled = body.distance_at_placement_mm(idx @ lin.T + aff[:3, 3])
    spacing = 0.5 * float(np.linalg.norm(lin / 8.0, axis=0).sum())
    assert exact <= sampled.min() + 1e-9
    assert sampled.min() - exact <= spacing
