"""Clearance between the swept drill and the landmarks, the maximum safe depth and the
landmark that binds it.

The drill solid at tip depth ``x`` is a cylinder of radius ``R`` from far outside the patient
to depth ``x - l_t`` plus the cone of length ``l_t`` ending at the tip (DESIGN.md section 2).
The clearance to a landmark is signed (negative when the drill enters it), so a margin of 0
means "touch, never cross". The solid only grows with depth, so every clearance is
non-increasing in depth; :func:`safe_depth` relies on that.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ctdrill.imaging.plan.clinical import CLINICAL_MARGIN_MM
from ctdrill.imaging.plan.distance import SEGMENT_TOL_MM, DrillSolid
from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.types import Plan
from ctdrill.warning_codes import LoadWarning

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


#: Clearance of rows at depths: ``(rows (n,), depths (n, P)) -> (n, P, L)`` signed, mm.
ClearanceAt = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class SafeDepths:
    """:class:`SafeDepth` of ``N`` rows (NaN / -1 / False in rows not searched).

    Attributes
    ----------
    depth_mm : (N,) deepest safe tip depth, mm.
    binding : (N,) int64 landmark whose margin is crossed just past it (-1: none, capped).
    capped : (N,) bool, the search reached its limit safely.
    """

    depth_mm: np.ndarray
    binding: np.ndarray
    capped: np.ndarray

    def row(self, i: int) -> SafeDepth:
        """Row ``i`` as a :class:`SafeDepth`."""
        b = int(self.binding[i])
        return SafeDepth(float(self.depth_mm[i]), None if b < 0 else b, bool(self.capped[i]))


def search_safe_depths(
    clearance_at: ClearanceAt,
    margins: np.ndarray,
    limit_mm: np.ndarray,
    rows: np.ndarray,
    *,
    tol_mm: float = SAFE_DEPTH_TOL_MM,
    bracket_mm: np.ndarray | None = None,
) -> SafeDepths:
    """Deepest tip depth of each row whose clearance to every landmark stays >= its margin.

    The one safe-depth rule (the single plan's :func:`safe_depth` and the engine's batch use
    it with their own clearance arrays). Found by bracketing on ``[0, limit_mm]`` (a row whose
    margins hold at the limit is capped there at once) and passes of :data:`_REFINE_POINTS`
    depths spanning the bracket (its ends included), each keeping
    the step where the slack (clearance - margin - :data:`SEGMENT_TOL_MM`) first turns
    negative (valid because the slack never increases with depth), to ``tol_mm``; the depth
    returned is on the safe side of the boundary. A clearance counts as kept only when it is
    at least the margin plus the distance tolerance, so the stop never lies past the true
    safe depth.

    Parameters
    ----------
    clearance_at : the clearance of rows at depths (:data:`ClearanceAt`).
    margins : (L,) margin per landmark, mm (L >= 1).
    limit_mm : (N,) search limit per row (the result is capped at it), mm.
    rows : the rows to search.
    tol_mm : tolerance, mm.
    bracket_mm : optional (N, 2) ``(lo, hi)`` with the margin kept at ``lo`` and violated at
        ``hi`` (e.g. from a clearance profile on a depth grid; NaN for none); checked in the
        first pass, and the full range searched where it does not hold.
    """
    n = limit_mm.shape[0]
    out = SafeDepths(np.full(n, np.nan), np.full(n, -1, dtype=np.int64), np.zeros(n, bool))
    todo = np.asarray(rows, dtype=np.int64)
    if bracket_mm is not None and todo.size:
        lo, hi = bracket_mm[todo, 0], bracket_mm[todo, 1]
        with np.errstate(invalid="ignore"):
            valid = (lo >= 0.0) & (lo < hi) & (hi <= limit_mm[todo])
        sub = todo[valid]
        found = _refine_rows(clearance_at, margins, sub, lo[valid], hi[valid], tol_mm, out)
        kept = found & (out.depth_mm[sub] < hi[valid])  # safe at lo, violated by hi
        todo = todo[~np.isin(todo, sub[kept])]
    if todo.size:  # safe at the limit: safe all the way (the slack never increases)
        end = clearance_at(todo, limit_mm[todo][:, None])[:, 0] - margins - SEGMENT_TOL_MM
        held = np.min(end, axis=1) >= 0.0
        out.depth_mm[todo[held]] = limit_mm[todo[held]]
        out.binding[todo[held]] = -1
        out.capped[todo[held]] = True
        todo = todo[~held]
    found = _refine_rows(
        clearance_at, margins, todo, np.zeros(todo.size), limit_mm[todo], tol_mm, out
    )
    at_entry = todo[~found]  # violated at the entry already
    if at_entry.size:
        slack = clearance_at(at_entry, np.zeros((at_entry.size, 1)))[:, 0] - margins
        out.depth_mm[at_entry] = 0.0
        out.binding[at_entry] = np.argmin(slack, axis=1)
        out.capped[at_entry] = False
    return out


def _refine_rows(
    clearance_at: ClearanceAt,
    margins: np.ndarray,
    rows: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    tol_mm: float,
    out: SafeDepths,
) -> np.ndarray:
    """Deepest safe depth of ``rows`` in ``[lo, hi]`` to ``tol_mm`` into ``out``; returns
    (n,) bool, False where ``lo`` is not safe (``out`` untouched there). ``hi`` still safe:
    ``hi``, capped."""
    found = np.ones(rows.size, dtype=bool)
    active = np.arange(rows.size)
    lo, hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    while active.size:
        xs = np.linspace(lo[active], hi[active], _REFINE_POINTS, axis=1)
        slack = clearance_at(rows[active], xs) - margins - SEGMENT_TOL_MM
        bad = np.min(slack, axis=2) < 0.0
        first = np.argmax(bad, axis=1)
        safe_all = ~bad.any(axis=1)
        done = rows[active[safe_all]]
        out.depth_mm[done] = hi[active[safe_all]]
        out.binding[done] = -1
        out.capped[done] = True
        unsafe_lo = ~safe_all & (first == 0)
        found[active[unsafe_lo]] = False
        go = ~safe_all & ~unsafe_lo
        k = np.flatnonzero(go)
        lo[active[k]] = xs[k, first[k] - 1]
        hi[active[k]] = xs[k, first[k]]
        close = hi[active[k]] - lo[active[k]] <= tol_mm
        fin = k[close]
        out.depth_mm[rows[active[fin]]] = lo[active[fin]]
        out.binding[rows[active[fin]]] = np.argmin(slack[fin, first[fin]], axis=1)
        out.capped[rows[active[fin]]] = False
        active = active[k[~close]]
    return found


def numpy_clearance_at(plan: Plan, landmarks: tuple[Landmark, ...]) -> ClearanceAt:
    """:data:`ClearanceAt` of the single ``plan`` (its row 0), the landmarks' own distances."""

    def at(rows: np.ndarray, depths: np.ndarray) -> np.ndarray:
        return np.stack([clearance_profile_mm(plan, landmarks, d) for d in depths])

    return at


def safe_depth(
    plan: Plan,
    landmarks: tuple[Landmark, ...] | None = None,
    *,
    limit_mm: float | None = None,
    tol_mm: float = SAFE_DEPTH_TOL_MM,
    bracket_mm: tuple[float, float] | None = None,
) -> SafeDepth:
    """Deepest tip depth whose clearance to every landmark stays >= its margin
    (:func:`search_safe_depths` for the one plan).

    Each landmark uses its own ``margin_mm`` when set, else ``plan.margin_mm``; the returned
    depth is on the safe side of the boundary (within ``tol_mm`` of it).

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
    bracket = None if bracket_mm is None else np.array([bracket_mm], dtype=np.float64)
    return search_safe_depths(
        numpy_clearance_at(plan, lms),
        margins_mm(plan, lms),
        np.array([limit]),
        np.array([0]),
        tol_mm=tol_mm,
        bracket_mm=bracket,
    ).row(0)


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


def margin_warnings(
    plan: Plan, plan_clearance_mm: np.ndarray, margins: np.ndarray
) -> list[LoadWarning]:
    """The warnings of a plan that breaks a margin or uses a sub-clinical one.

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
    out: list[LoadWarning] = []
    broken = [
        f"{lm.name!r} {float(c):.3f} mm (margin {float(m):g} mm"
        + (", inside it)" if c < 0.0 else ")")
        for lm, c, m in zip(plan.landmarks, plan_clearance_mm, margins, strict=True)
        if c < m
    ]
    if broken:
        out.append(
            LoadWarning(
                "plan_violates_margin",
                f"plan {plan.name!r}: the planned path breaks the safety margin: clearance at "
                f"the planned depth {plan.planned_depth_mm:.3f} mm to " + ", ".join(broken),
            )
        )
    low = sorted({float(m) for m in margins} | ({plan.margin_mm} if not plan.landmarks else set()))
    low = [m for m in low if m < CLINICAL_MARGIN_MM]
    if low:
        out.append(
            LoadWarning(
                "margin_below_clinical",
                f"plan {plan.name!r}: safety margin {', '.join(f'{m:g}' for m in low)} mm is "
                f"below the clinical {CLINICAL_MARGIN_MM:g} mm to the nerve canal",
            )
        )
    return out
