"""Property test: the stop never lies past the true safe depth, for random canals, points,
masks (on oblique, sheared grids), drills and margins (0 included).

The reference is independent of ``ctdrill.imaging.plan.distance``: the signed distance to
the convex drill solid from its support function, ``sd(u) = max_e (e . u - h(e))`` over unit
directions ``e`` (exact for any convex body, inside and outside). In the meridian plane of
``u`` (axial ``s``, radial ``rho`` >= 0, tip at depth ``x``), ``h`` is attained at the tip or
at the corner circle, which makes it the maximum over ``theta`` in ``[0, pi/2]`` of
``min(g_tip, g_corner)``, with ``g_tip = (s - x) cos + rho sin`` and
``g_corner = (s - x + l_t) cos + (rho - R) sin``; ``g_tip <= g_corner`` exactly for
``tan(theta) <= l_t / R``. Each piece is a sinusoid, maximal at an end or where its
derivative vanishes: a closed form. The landmark is sampled densely (its samples lie on it),
so the sampled clearance ``C_ref`` is at least the true one and at most ``h`` above it
(``h``: the farthest any landmark point is from a sample). Hence

- the true safe depth is at most ``x_hi`` (deepest depth with ``C_ref >= margin``), and the
  stop must not exceed it;
- it is at least ``x_lo`` (deepest depth with ``C_ref - h >= margin``), and the stop must
  not be more than the search tolerance shallower than that (no needless stop).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark, PointLandmark
from ctdrill.imaging.plan.safety import SAFE_DEPTH_TOL_MM, max_safe_depth_mm, search_limit_mm
from ctdrill.imaging.plan.types import DrillSpec, Plan


def _sinusoid_max(a: np.ndarray, b: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """max of ``a cos(t) + b sin(t)`` over ``t`` in ``[lo, hi]`` (within ``[0, pi/2]``)."""
    best = np.maximum(a * math.cos(lo) + b * math.sin(lo), a * math.cos(hi) + b * math.sin(hi))
    t = np.arctan2(b, a)
    inside = (t >= lo) & (t <= hi)
    return np.where(inside, np.maximum(best, np.hypot(a, b)), best)


def reference_sd(s: np.ndarray, rho: np.ndarray, x: float, r: float, lt: float) -> np.ndarray:
    """Signed distance to the drill solid by its support function (see the module doc)."""
    theta_c = math.atan2(lt, r)
    tip = _sinusoid_max(s - x, rho, 0.0, theta_c)
    corner = _sinusoid_max(s - x + lt, rho - r, theta_c, math.pi / 2)
    return np.maximum(tip, corner)


def _samples(
    kind: str, rng: np.random.Generator, centre: np.ndarray
) -> tuple[object, np.ndarray, float, float]:
    """A random landmark near ``centre``: (landmark, samples on its core, radius, gap h)."""
    if kind == "point":
        pt = centre + rng.normal(size=3)
        return PointLandmark("p", pt), pt[None, :], 0.0, 0.0
    if kind == "canal":
        n = int(rng.integers(2, 5))
        pts = centre + np.cumsum(rng.normal(size=(n, 3)) * 3.0, axis=0)
        pts -= pts.mean(axis=0) - centre
        radius = float(rng.choice([0.0, rng.uniform(0.0, 1.5)]))
        step = 0.004
        dense = [
            a
            + np.linspace(0.0, 1.0, max(2, math.ceil(np.linalg.norm(b - a) / step)))[:, None]
            * (b - a)
            for a, b in itertools.pairwise(pts)
        ]
        return (
            CanalLandmark("c", pts, radius_mm=radius),
            np.concatenate(dense),
            radius,
            step / 2.0,
        )
    lin = np.diag(rng.uniform(0.3, 1.0, 3)) + rng.normal(size=(3, 3)) * 0.15
    mask = rng.random((3, 3, 3)) < 0.45
    mask[1, 1, 1] = True
    affine = np.eye(4)
    affine[:3, :3] = lin
    affine[:3, 3] = centre - lin @ np.ones(3)
    k = 9
    g = np.linspace(-0.5, 0.5, k)
    sub = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    ijk = (np.argwhere(mask)[:, ::-1][:, None, :] + sub[None]).reshape(-1, 3)
    h = float(np.linalg.norm(lin, axis=0).sum()) / (k - 1) / 2.0
    return MaskLandmark("m", mask, affine_lps=affine), ijk @ lin.T + affine[:3, 3], 0.0, h


def _deepest(ok: object, limit: float) -> float:
    """Deepest x in [0, limit] with ``ok(x)`` (monotone: true then false), to 1e-7 mm."""
    assert callable(ok)
    if ok(limit):
        return limit
    if not ok(0.0):
        return 0.0
    lo, hi = 0.0, limit
    while hi - lo > 1e-7:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


@settings(max_examples=80, deadline=None)
@given(
    kind=st.sampled_from(["canal", "point", "mask"]),
    seed=st.integers(0, 2**31),
    radius=st.floats(0.3, 1.5),
    tip=st.one_of(st.just(0.0), st.floats(0.1, 1.2)),  # 0: a flat-ended drill
    margin=st.one_of(st.just(0.0), st.floats(0.0, 3.0)),
    depth_at=st.floats(2.0, 16.0),
    offset=st.floats(0.0, 3.0),
)
def test_the_stop_never_passes_the_true_safe_depth(
    kind: str, seed: int, radius: float, tip: float, margin: float, depth_at: float, offset: float
) -> None:
    rng = np.random.default_rng(seed)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    entry = rng.uniform(-20.0, 20.0, size=3)
    side = np.cross(u, rng.normal(size=3))
    side /= np.linalg.norm(side)
    centre = entry + depth_at * u + offset * side
    landmark, samples, lm_radius, gap = _samples(kind, rng, centre)
    plan = Plan(
        entry_lps=entry,
        target_lps=entry + 15.0 * u,
        drill=DrillSpec(diameter_mm=2.0 * radius, tip_length_mm=tip),
        margin_mm=margin,
        landmarks=(landmark,),  # type: ignore[arg-type]
    )
    stop = max_safe_depth_mm(plan)
    limit = search_limit_mm(plan)

    rel = samples - entry
    s = rel @ u
    rho = np.linalg.norm(rel - s[:, None] * u, axis=1)

    def c_ref(x: float) -> float:
        return float(reference_sd(s, rho, x, radius, tip).min()) - lm_radius

    x_hi = _deepest(lambda x: c_ref(x) >= margin, limit)
    x_lo = _deepest(lambda x: c_ref(x) - gap >= margin, limit)
    assert stop <= x_hi + 1e-9
    assert stop >= x_lo - SAFE_DEPTH_TOL_MM - 1e-6


def test_the_reference_agrees_with_closed_forms() -> None:
    r, lt = 1.0, 0.6
    s = np.array([7.0, 4.0, -100.0, -100.0, 4.4])
    rho = np.array([0.0, 3.0, 0.0, 0.5, 0.0])
    want = [2.0, 2.0, -1.0, -0.5, -0.6 / math.hypot(r, lt)]
    np.testing.assert_allclose(reference_sd(s, rho, 5.0, r, lt), want, atol=1e-12)
