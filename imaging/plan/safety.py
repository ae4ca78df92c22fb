"""Clearance between the swept drill and the landmarks, and the maximum safe depth.

The drill solid at tip depth ``x`` is a cylinder of radius ``R`` from far outside the patient
to depth ``x - l_t`` plus the cone of length ``l_t`` ending at the tip (DESIGN.md section 2).
The clearance to a landmark is ``distance(solid, landmark core) - landmark radius`` (mm,
negative when the drill enters the landmark). The solid only grows with depth, so every
clearance is non-increasing in depth; :func:`max_safe_depth_mm` relies on that.
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.plan.distance import (
    axial_coordinates,
    segment_solid_distance_mm,
    solid_distance_mm,
)
from ctdrill.imaging.plan.landmarks import Landmark, landmark_core
from ctdrill.imaging.plan.types import Plan

#: Tolerance of :func:`max_safe_depth_mm`, mm.
SAFE_DEPTH_TOL_MM = 1e-3
#: Depths evaluated per refinement pass of :func:`max_safe_depth_mm`.
_REFINE_POINTS = 65
#: Points per chunk when a landmark core has many points (mask voxels), to bound memory.
_CHUNK_POINTS = 4096


def _core_distance_mm(plan: Plan, landmark: Landmark, depth_mm: np.ndarray) -> np.ndarray:
    """(D,) distance from the drill solid to the landmark's core at each depth, mm."""
    a, b, _ = landmark_core(landmark)
    r = plan.drill.radius_mm
    lt = plan.drill.tip_length_mm
    if a is b or np.array_equal(a, b):  # points (point landmark, mask voxels): closed form
        s, perp = axial_coordinates(a, plan.entry_lps, plan.direction)
        rho = np.linalg.norm(perp, axis=-1)
        best = np.full(depth_mm.shape, np.inf)
        for start in range(0, len(s), _CHUNK_POINTS):
            sl = slice(start, start + _CHUNK_POINTS)
            d = solid_distance_mm(
                s[None, sl], rho[None, sl], depth_mm[:, None], radius_mm=r, tip_length_mm=lt
            )
            best = np.minimum(best, d.min(axis=1))
        return best
    return segment_solid_distance_mm(
        a,
        b,
        depth_mm,
        entry_lps=plan.entry_lps,
        direction=plan.direction,
        radius_mm=r,
        tip_length_mm=lt,
    )


def clearance_profile_mm(
    plan: Plan, landmarks: tuple[Landmark, ...] | None = None, depth_mm: np.ndarray | None = None
) -> np.ndarray:
    """Clearance from the drill solid to each landmark's surface at each tip depth.

    Parameters
    ----------
    plan : the trajectory and drill.
    landmarks : (L,) landmarks (default: ``plan.landmarks``); mask landmarks must have a grid.
    depth_mm : (D,) tip depths from the entry, mm (default: a single depth, the planned one).

    Returns
    -------
    (D, L) clearance, mm; negative inside a landmark.
    """
    lms = plan.landmarks if landmarks is None else landmarks
    depth = (
        np.array([plan.planned_depth_mm])
        if depth_mm is None
        else np.asarray(depth_mm, dtype=np.float64).reshape(-1)
    )
    out = np.empty((depth.shape[0], len(lms)))
    for j, lm in enumerate(lms):
        out[:, j] = _core_distance_mm(plan, lm, depth) - lm.radius_mm
    return out


def clearance_mm(plan: Plan, landmark: Landmark, depth_mm: float) -> float:
    """Clearance from the drill at tip depth ``depth_mm`` to one landmark's surface, mm."""
    return float(clearance_profile_mm(plan, (landmark,), np.array([depth_mm]))[0, 0])


def max_safe_depth_mm(
    plan: Plan,
    landmarks: tuple[Landmark, ...] | None = None,
    *,
    limit_mm: float | None = None,
    tol_mm: float = SAFE_DEPTH_TOL_MM,
    bracket_mm: tuple[float, float] | None = None,
) -> float:
    """Deepest tip depth whose clearance to every landmark stays >= its margin, mm.

    Each landmark uses its own ``margin_mm`` when set, else ``plan.margin_mm``. Found by
    bracketing on ``[0, limit_mm]`` and refinement (64-section, i.e. six bisection steps per
    vectorised pass) to ``tol_mm``; the returned depth is on the safe side of the boundary
    (within ``tol_mm`` of it).

    Parameters
    ----------
    limit_mm : search limit (default: the planned depth + 10 mm). The result is capped at it:
        a value equal to ``limit_mm`` means "safe at least that deep"; with no landmark it is
        ``limit_mm``.
    bracket_mm : optional ``(lo, hi)`` with the margin kept at ``lo`` and violated at
        ``hi`` (e.g. from a clearance profile on a depth grid); checked in the first pass, and
        the full range searched when it does not hold.

    Returns
    -------
    Depth in ``[0, limit_mm]``, mm; 0 when the margin is already violated at the entry.
    """
    lms = plan.landmarks if landmarks is None else landmarks
    limit = plan.planned_depth_mm + 10.0 if limit_mm is None else float(limit_mm)
    if not lms:
        return limit
    margins = np.array([plan.landmark_margin_mm(lm) for lm in lms])
    if bracket_mm is not None:
        lo, hi = float(bracket_mm[0]), float(bracket_mm[1])
        if 0.0 <= lo < hi <= limit:
            found = _refine(plan, lms, margins, lo, hi, tol_mm)
            if found is not None and found < hi:  # safe at lo, violated by hi: it held
                return found
    found = _refine(plan, lms, margins, 0.0, limit, tol_mm)
    if found is None:  # violated at the entry already
        return 0.0
    return found


def _refine(
    plan: Plan,
    lms: tuple[Landmark, ...],
    margins: np.ndarray,
    lo: float,
    hi: float,
    tol_mm: float,
) -> float | None:
    """Deepest safe depth in ``[lo, hi]`` to ``tol_mm``, or None if ``lo`` is not safe.

    Each pass evaluates ``_REFINE_POINTS`` depths spanning the bracket (its ends included) in
    one vectorised call and keeps the step where the slack (clearance - margin) first turns
    negative, valid because the slack never increases with depth: the bracket shrinks
    ``_REFINE_POINTS - 1``-fold per pass. Returns ``hi`` when it is still safe.
    """
    while True:
        xs = np.linspace(lo, hi, _REFINE_POINTS)
        slack = np.min(clearance_profile_mm(plan, lms, xs) - margins[None, :], axis=1)
        bad = np.flatnonzero(slack < 0.0)
        if bad.size == 0:
            return hi
        first = int(bad[0])
        if first == 0:
            return None
        lo, hi = float(xs[first - 1]), float(xs[first])
        if hi - lo <= tol_mm:
            return lo


def nearest_landmark(clearance_mm: np.ndarray, margins_mm: np.ndarray) -> int | None:
    """Index of the landmark with the smallest clearance minus margin over all depths.

    Parameters
    ----------
    clearance_mm : (D, L) clearance profile.
    margins_mm : (L,) margin per landmark.
    """
    if clearance_mm.shape[1] == 0 or clearance_mm.shape[0] == 0:
        return None
    return int(np.argmin(clearance_mm.min(axis=0) - margins_mm))
