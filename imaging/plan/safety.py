"""Clearance between the swept drill and the landmarks, the maximum safe depth and the
landmark that binds it.

The drill solid at tip depth ``x`` is a cylinder of radius ``R`` from far outside the patient
to depth ``x - l_t`` plus the cone of length ``l_t`` ending at the tip (DESIGN.md section 2).
The clearance to a landmark is signed (negative when the drill enters it), so a margin of 0
means "touch, never cross". The solid only grows with depth, so every clearance is
non-increasing in depth; :func:`safe_depth` relies on that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.imaging.plan.clinical import CLINICAL_MARGIN_MM
from ctdrill.imaging.plan.distance import SEGMENT_TOL_MM, DrillSolid
from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.types import Plan

#: Tolerance of :func:`safe_depth`, mm.
SAFE_DEPTH_TOL_MM = 1e-3
#: How far past the planned depth the safe-depth search looks, mm (its one owner): a max
#: safe depth at ``planned + this`` means "safe at least that deep".
SEARCH_BEYOND_PLAN_MM = 10.0
#: Depths evaluated per refinement pass of :func:`safe_depth`.
_REFINE_POINTS = 65


def search_limit_mm(plan: Plan) -> float:
    """Deepest depth the safe-depth search looks at: planned + :data:`SEARCH_BEYOND_PLAN_MM`."""
    return plan.planned_depth_mm + SEARCH_BEYOND_PLAN_MM


def drill_solid(plan: Plan) -> DrillSolid:
    """The plan's drill axis and shape."""
    return DrillSolid(
        plan.entry_lps, plan.direction, plan.drill.radius_mm, plan.drill.tip_length_mm
    )


def clearance_profile_mm(
    plan: Plan, landmarks: tuple[Landmark, ...] | None = None, depth_mm: np.ndarray | None = None
) -> np.ndarray:
    """Signed clearance from the drill solid to each landmark at each tip depth.

    Parameters
    ----------
    plan : the trajectory and drill.
    landmarks : (L,) landmarks (default: ``plan.landmarks``); mask landmarks must have a grid.
    depth_mm : (D,) tip depths from the entry, mm (default: a single depth, the planned one).

    Returns
    -------
    (D, L) clearance, mm; negative inside a landmark. Exact to
    :data:`~ctdrill.imaging.plan.distance.SEGMENT_TOL_MM` (never below the true value).
    """
    lms = plan.landmarks if landmarks is None else landmarks
    depth = (
        np.array([plan.planned_depth_mm])
        if depth_mm is None
        else np.asarray(depth_mm, dtype=np.float64).reshape(-1)
    )
    out = np.empty((depth.shape[0], len(lms)))
    if not lms:
        return out
    solid = drill_solid(plan)
    for j, lm in enumerate(lms):
        out[:, j] = lm.clearance_mm(solid, depth)
    return out


def clearance_mm(plan: Plan, landmark: Landmark, depth_mm: float) -> float:
    """Clearance from the drill at tip depth ``depth_mm`` to one landmark's surface, mm."""
    return float(clearance_profile_mm(plan, (landmark,), np.array([depth_mm]))[0, 0])


def margins_mm(plan: Plan, landmarks: tuple[Landmark, ...] | None = None) -> np.ndarray:
    """(L,) the margin that applies to each landmark (its own, else the plan's), mm."""
    lms = plan.landmarks if landmarks is None else landmarks
    return np.array([plan.landmark_margin_mm(lm) for lm in lms], dtype=np.float64)


@dataclass(frozen=True)
class SafeDepth:
    """The deepest safe tip depth and what sets it.

    Attributes
    ----------
    depth_mm : deepest depth whose clearance to every landmark stays >= its margin, mm.
    binding : index of the landmark whose margin is crossed just past ``depth_mm`` (None
        when no margin is crossed within the search, i.e. ``capped``).
    capped : the search reached its limit safely: "safe at least ``depth_mm`` deep".
    """

    depth_mm: float
    binding: int | None
    capped: bool


def safe_depth(
    plan: Plan,
    landmarks: tuple[Landmark, ...] | None = None,
    *,
    limit_mm: float | None = None,
    tol_mm: float = SAFE_DEPTH_TOL_MM,
    bracket_mm: tuple[float, float] | None = None,
) -> SafeDepth:
    """Deepest tip depth whose clearance to every landmark stays >= its margin.

    Each landmark uses its own ``margin_mm`` when set, else ``plan.margin_mm``. Found by
    bracketing on ``[0, limit_mm]`` and refinement (64-section, i.e. six bisection steps per
    vectorised pass) to ``tol_mm``; the returned depth is on the safe side of the boundary
    (within ``tol_mm`` of it). A clearance counts as kept only when it is at least the margin
    plus the distance tolerance, so the stop never lies past the true safe depth.

    Parameters
    ----------
    limit_mm : search limit (default :func:`search_limit_mm`). The result is capped at it.
    bracket_mm : optional ``(lo, hi)`` with the margin kept at ``lo`` and violated at
        ``hi`` (e.g. from a clearance profile on a depth grid); checked in the first pass, and
        the full range searched when it does not hold.
    """
    lms = plan.landmarks if landmarks is None else landmarks
    limit = search_limit_mm(plan) if limit_mm is None else float(limit_mm)
    if not lms:
        return SafeDepth(limit, None, True)
    margins = margins_mm(plan, lms)
    if bracket_mm is not None:
        lo, hi = float(bracket_mm[0]), float(bracket_mm[1])
        if 0.0 <= lo < hi <= limit:
            found = _refine(plan, lms, margins, lo, hi, tol_mm)
            if found is not None and found.depth_mm < hi:  # safe at lo, violated by hi
                return found
    found = _refine(plan, lms, margins, 0.0, limit, tol_mm)
    if found is None:  # violated at the entry already
        slack = clearance_profile_mm(plan, lms, np.array([0.0]))[0] - margins
        return SafeDepth(0.0, int(np.argmin(slack)), False)
    return found


def max_safe_depth_mm(
    plan: Plan,
    landmarks: tuple[Landmark, ...] | None = None,
    *,
    limit_mm: float | None = None,
    tol_mm: float = SAFE_DEPTH_TOL_MM,
    bracket_mm: tuple[float, float] | None = None,
) -> float:
    """:attr:`SafeDepth.depth_mm` of :func:`safe_depth`, mm."""
    return safe_depth(
        plan, landmarks, limit_mm=limit_mm, tol_mm=tol_mm, bracket_mm=bracket_mm
    ).depth_mm


def _refine(
    plan: Plan,
    lms: tuple[Landmark, ...],
    margins: np.ndarray,
    lo: float,
    hi: float,
    tol_mm: float,
) -> SafeDepth | None:
    """Deepest safe depth in ``[lo, hi]`` to ``tol_mm``, or None if ``lo`` is not safe.

    Each pass evaluates ``_REFINE_POINTS`` depths spanning the bracket (its ends included) in
    one vectorised call and keeps the step where the slack (clearance - margin) first turns
    negative, valid because the slack never increases with depth: the bracket shrinks
    ``_REFINE_POINTS - 1``-fold per pass. Returns ``hi`` (capped) when it is still safe.
    """
    while True:
        xs = np.linspace(lo, hi, _REFINE_POINTS)
        slack = clearance_profile_mm(plan, lms, xs) - margins[None, :] - SEGMENT_TOL_MM
        bad = np.flatnonzero(np.min(slack, axis=1) < 0.0)
        if bad.size == 0:
            return SafeDepth(hi, None, True)
        first = int(bad[0])
        if first == 0:
            return None
        lo, hi = float(xs[first - 1]), float(xs[first])
        if hi - lo <= tol_mm:
            return SafeDepth(lo, int(np.argmin(slack[first])), False)


def margin_warnings(
    plan: Plan, plan_clearance_mm: np.ndarray, margins: np.ndarray
) -> list[tuple[str, str]]:
    """``(code, message)`` for a plan that breaks a margin or uses a sub-clinical one.

    Parameters
    ----------
    plan : the plan (landmark names, margins).
    plan_clearance_mm : (L,) signed clearance at the planned depth (the smallest along the
        planned path, as clearance never increases with depth), mm.
    margins : (L,) margin per landmark, mm.

    Returns
    -------
    ``plan_violates_margin`` (one message naming every landmark whose margin the planned path
    breaks) and ``margin_below_clinical`` (every margin under :data:`CLINICAL_MARGIN_MM`,
    0 included), in that order; empty when neither applies.
    """
    out: list[tuple[str, str]] = []
    broken = [
        f"{lm.name!r} {float(c):.3f} mm (margin {float(m):g} mm"
        + (", inside it)" if c < 0.0 else ")")
        for lm, c, m in zip(plan.landmarks, plan_clearance_mm, margins, strict=True)
        if c < m
    ]
    if broken:
        out.append(
            (
                "plan_violates_margin",
                f"plan {plan.name!r}: the planned path breaks the safety margin: clearance at "
                f"the planned depth {plan.planned_depth_mm:.3f} mm to " + ", ".join(broken),
            )
        )
    low = sorted({float(m) for m in margins} | ({plan.margin_mm} if not plan.landmarks else set()))
    low = [m for m in low if m < CLINICAL_MARGIN_MM]
    if low:
        out.append(
            (
                "margin_below_clinical",
                f"plan {plan.name!r}: safety margin {', '.join(f'{m:g}' for m in low)} mm is "
                f"below the clinical {CLINICAL_MARGIN_MM:g} mm to the nerve canal",
            )
        )
    return out
