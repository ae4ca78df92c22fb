"""Clearance, safe depth and stop of every row: the path's safety rules, written once.

The clearance arrays come from :class:`~ctdrill.imaging.plan.clearance_batch.ClearanceField`
(the compiled kernel or the landmarks' own distances: the same arrays); the safe depth is
:func:`~ctdrill.imaging.plan.safety.search_safe_depths`, started from the grid step where a
margin is first broken; the stop is ``min(planned depth, max safe depth, where the lip leaves
the scan)``, ties to the first listed (:data:`STOP_REASONS`); the binding landmark is the
one whose margin sets the max safe depth, else the one nearest the drill at the stop.

With ``full_grid=False`` (a search that reads only the stops: ``suggest``) the clearance is
not computed on the whole grid: the grid step where a margin is first broken is found on every
:data:`COARSE_EVERY`-th grid depth (the planned depth among them), then on the grid depths of
the one coarse step that holds it. The clearance never increases with depth (the drill solid
only grows), so that is the step the whole grid gives, and the stops are the same.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.engine.grid import grid_brackets
from ctdrill.engine.stop import StopReason
from ctdrill.imaging.plan.clearance_batch import ClearanceField
from ctdrill.imaging.plan.distance import SEGMENT_TOL_MM
from ctdrill.imaging.plan.safety import SEARCH_BEYOND_PLAN_MM, search_safe_depths

#: Stop reasons in the order ties are broken (the first listed wins).
STOP_REASONS = tuple(StopReason)
#: Without the full grid, the first broken margin is looked for on every this-many-th grid
#: depth first (then on the grid depths of one coarse step): about ``2 sqrt(D)`` depths.
COARSE_EVERY = 16


@dataclass(frozen=True, eq=False)
class Stops:
    """Per-row clearances and stops (NaN / -1 / "" in rows not computed).

    Attributes
    ----------
    clearance_mm : (N, D, L) signed clearance per grid depth and landmark, mm.
    max_safe_depth_mm : (N,) deepest safe depth, mm.
    capped : (N,) bool, the search reached its limit safely.
    binding : (N,) int64 binding landmark (-1 none).
    plan_clearance_mm : (N,) smallest clearance over the planned path, mm (NaN: no landmark).
    stop_depth_mm : (N,) min(planned, max safe, out of volume), mm.
    stop_reason : (N,) object, one of :data:`STOP_REASONS`.
    stop_clearance_mm : (N, L) clearance at the stop depth, mm.
    """

    clearance_mm: np.ndarray
    max_safe_depth_mm: np.ndarray
    capped: np.ndarray
    binding: np.ndarray
    plan_clearance_mm: np.ndarray
    stop_depth_mm: np.ndarray
    stop_reason: np.ndarray
    stop_clearance_mm: np.ndarray


def evaluate_stops(
    field: ClearanceField,
    margins: np.ndarray,
    depth_mm: np.ndarray,
    n_depths: np.ndarray,
    planned_mm: np.ndarray,
    out_of_volume_mm: np.ndarray,
    rows: np.ndarray,
    *,
    full_grid: bool = True,
) -> Stops:
    """Clearances on each row's grid, its max safe depth, stop and binding landmark.

    Parameters
    ----------
    field : the clearance of every row's axis.
    margins : (L,) margin per landmark, mm.
    depth_mm, n_depths : (N, D) each row's grid and its length.
    planned_mm : (N,) planned depths, mm.
    out_of_volume_mm : (N,) where the lip leaves the scan (NaN: not before the planned depth).
    rows : the rows to compute.
    full_grid : False: ``clearance_mm`` is NaN except at each row's planned depth (its last
        grid depth), and the first broken margin is found on a sparse part of the grid
        (module docstring); the stops are the same.
    """
    n, d_max = depth_mm.shape
    n_l = margins.shape[0]
    rows = np.asarray(rows, dtype=np.int64)
    clear = np.full((n, d_max, n_l), np.nan)
    if full_grid:
        clear[rows] = field.at(rows, np.nan_to_num(depth_mm[rows]), n_depths[rows])
        brackets = grid_brackets(depth_mm, n_depths, clear, margins)
    else:
        brackets = _sparse_brackets(field, margins, depth_mm, n_depths, rows, clear)
    limit = planned_mm + SEARCH_BEYOND_PLAN_MM
    if n_l:
        # the search's passes read each row up to its first broken depth: no further
        slack = (margins, SEGMENT_TOL_MM)
        safe = search_safe_depths(
            lambda r, x: field.at(r, x, stop_slack=slack),
            margins,
            limit,
            rows,
            bracket_mm=brackets,
        )
        max_safe, capped, binding = safe.depth_mm, safe.capped, safe.binding
    else:  # nothing to keep away from: "safe at least" the search limit
        max_safe = np.where(np.isin(np.arange(n), rows), limit, np.nan)
        capped = np.isin(np.arange(n), rows)
        binding = np.full(n, -1, dtype=np.int64)
    oov = np.where(np.isnan(out_of_volume_mm), np.inf, out_of_volume_mm)
    stop = np.full(n, np.nan)
    code = np.zeros(n, dtype=np.int64)
    stop[rows] = planned_mm[rows]
    for c, depth in ((1, max_safe), (2, oov)):  # strictly smaller: ties to the first listed
        smaller = rows[depth[rows] < stop[rows]]
        stop[smaller] = depth[smaller]
        code[smaller] = c
    stop_clear = np.full((n, n_l), np.nan)
    plan_clear = np.full(n, np.nan)
    reason = np.full(n, "", dtype=object)
    if rows.size:
        stop_clear[rows] = field.at(rows, stop[rows, None])[:, 0]
        reason[rows] = np.array(STOP_REASONS, dtype=object)[code[rows]]
        if n_l:
            free = rows[binding[rows] < 0]  # no margin binds: the landmark nearest at the stop
            binding[free] = np.argmin(stop_clear[free], axis=1)
            plan_clear[rows] = np.min(clear[rows, n_depths[rows] - 1], axis=1)
    return Stops(clear, max_safe, capped, binding, plan_clear, stop, reason, stop_clear)


def _sparse_brackets(
    field: ClearanceField,
    margins: np.ndarray,
    depth_mm: np.ndarray,
    n_depths: np.ndarray,
    rows: np.ndarray,
    clear: np.ndarray,
) -> np.ndarray:
    """:func:`~ctdrill.engine.grid.grid_brackets` from the clearance of ``rows`` on every
    :data:`COARSE_EVERY`-th grid depth and the last, then on the grid depths of the coarse
    step where a margin is first broken; fills ``clear`` at the depths computed."""
    n_l = margins.shape[0]
    if not (rows.size and n_l and depth_mm.shape[1]):
        return np.full((depth_mm.shape[0], 2), np.nan)
    m = n_depths[rows]
    width = -(-(int(m.max()) - 1) // COARSE_EVERY) + 1
    # coarse indices 0, k, 2k, ... clipped to the last: repeated last ones change nothing
    coarse = np.minimum(np.arange(width)[None, :] * COARSE_EVERY, (m - 1)[:, None])
    got = field.at(rows, np.take_along_axis(depth_mm[rows], coarse, axis=1))
    clear[rows[:, None], coarse] = got
    with np.errstate(invalid="ignore"):
        bad = np.any(got < margins, axis=2)
    first = np.argmax(bad, axis=1)
    broken = bad.any(axis=1) & (first > 0)
    sub = np.flatnonzero(broken)
    if sub.size:  # the fine grid depths inside the coarse step: (its start, its end]
        start = coarse[sub, first[sub] - 1]
        fine = np.minimum(
            start[:, None] + 1 + np.arange(COARSE_EVERY)[None, :], coarse[sub, first[sub]][:, None]
        )
        r = rows[sub]
        fine_got = field.at(r, np.take_along_axis(depth_mm[r], fine, axis=1))
        clear[r[:, None], fine] = fine_got
    # the depths not computed are NaN: never "broken", so the first broken one is the grid's
    return grid_brackets(depth_mm, n_depths, clear, margins)
