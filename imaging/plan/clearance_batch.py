"""Clearances, max safe depth and stop of many trajectories at once (the batched
``safety.py``).

For ``N`` drill axes sharing one drill and one set of landmarks, :func:`evaluate_clearances`
returns per row what :func:`~ctdrill.imaging.plan.safety.clearance_profile_mm` and
:func:`~ctdrill.imaging.plan.safety.safe_depth` give for that axis, plus the stop depth, with
the compiled kernel of :mod:`ctdrill.imaging.plan.clearance_kernel` (how it finds each
minimum exactly is told there). Every landmark is handed to it as segments (a canal's
centreline and radius, a point, a mask's :func:`~ctdrill.imaging.plan.voxels.voxel_union_segments`
for each axis), as the landmark's own ``clearance_mm`` measures it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.imaging.plan.clearance_kernel import CLEARANCE_KERNEL
from ctdrill.imaging.plan.distance import SEGMENT_TOL_MM, DrillSolid
from ctdrill.imaging.plan.landmarks import CanalLandmark, Landmark, MaskLandmark, PointLandmark
from ctdrill.imaging.plan.safety import (
    _REFINE_POINTS,
    SAFE_DEPTH_TOL_MM,
    SEARCH_BEYOND_PLAN_MM,
)
from ctdrill.imaging.plan.voxels import voxel_union_segments
from ctdrill.jit import row_spans, run_spans

#: Stop reasons by code (``plan_path``'s order: ties go to the first).
STOP_REASONS = ("planned_depth", "margin", "out_of_volume")


@dataclass(frozen=True, eq=False)
class ClearanceBatch:
    """Per-row clearances and stops (NaN / -1 in rows not computed).

    Attributes
    ----------
    clearance_mm : (N, D, L) signed clearance per depth and landmark, mm.
    max_safe_depth_mm : (N,) deepest safe depth, mm.
    capped : (N,) bool, the search reached its limit safely.
    binding : (N,) int64 binding landmark (-1 none).
    stop_depth_mm : (N,) min(planned, max safe, out of volume), mm.
    stop_reason : (N,) int64 index into :data:`STOP_REASONS` (-1 not computed).
    stop_clearance_mm : (N, L) clearance at the stop depth, mm.
    """

    clearance_mm: np.ndarray
    max_safe_depth_mm: np.ndarray
    capped: np.ndarray
    binding: np.ndarray
    stop_depth_mm: np.ndarray
    stop_reason: np.ndarray
    stop_clearance_mm: np.ndarray


def landmark_segments(
    landmark: Landmark, solid: DrillSolid
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """``(a, b, radius)``: the segments whose nearest point to the solid gives the landmark's
    clearance (minus ``radius``), as its own ``clearance_mm`` measures them; None for a kind
    the kernel does not know (then the per-row path runs)."""
    if isinstance(landmark, CanalLandmark):
        a, b = landmark.segments_lps()
        return a, b, float(landmark.radius_mm)
    if isinstance(landmark, PointLandmark):
        pt = landmark.point_lps[None, :]
        return pt, pt, 0.0
    if isinstance(landmark, MaskLandmark) and landmark.affine_lps is not None:
        a, b = voxel_union_segments(landmark.mask, landmark.affine_lps, solid)
        return a, b, 0.0
    return None


def _unit_directions(entries: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Plan.direction normalised again as DrillSolid does."""
    d = targets - entries
    u = d / np.sqrt(np.sum(d * d, axis=1))[:, None]
    return np.asarray(u / np.sqrt(np.sum(u * u, axis=1))[:, None])


def evaluate_clearances(
    landmarks: tuple[Landmark, ...],
    margins_mm: np.ndarray,
    radius_mm: float,
    tip_length_mm: float,
    entries_lps: np.ndarray,
    targets_lps: np.ndarray,
    depth_mm: np.ndarray,
    n_depths: np.ndarray,
    planned_mm: np.ndarray,
    out_of_volume_mm: np.ndarray,
    rows: np.ndarray,
) -> ClearanceBatch | None:
    """Clearances, max safe depth and stop of ``rows`` with the compiled kernel.

    Parameters
    ----------
    landmarks : (L,) landmarks bound to the CT grid; margins_mm (L,) their margins.
    radius_mm, tip_length_mm : the drill.
    entries_lps, targets_lps : (N, 3) LPS mm.
    depth_mm, n_depths : (N, D) each row's depth grid (``depth_grid_mm``) and its length.
    planned_mm : (N,) each row's planned depth (``Plan.planned_depth_mm``), mm.
    out_of_volume_mm : (N,) where the lip's data end (inf: never before the planned depth).
    rows : the rows to compute.

    Returns
    -------
    ClearanceBatch | None
        None when the kernel is not compiled or a landmark kind is not known to it (the
        caller then uses the per-row functions of ``safety.py``).
    """
    if not CLEARANCE_KERNEL.ready():
        return None
    n, d_max = depth_mm.shape
    n_l = len(landmarks)
    entries = np.ascontiguousarray(entries_lps, dtype=np.float64)
    targets = np.ascontiguousarray(targets_lps, dtype=np.float64)
    todo = np.asarray(rows, dtype=np.int64)
    dirs = np.zeros((n, 3))
    dirs[todo] = _unit_directions(entries[todo], targets[todo])
    starts: list[np.ndarray] = []
    ends: list[np.ndarray] = []
    radii_l = np.zeros(n_l)
    ptr = np.zeros((n, n_l, 2), dtype=np.int64)
    at = 0
    for lm_i, lm in enumerate(landmarks):
        shared = not isinstance(lm, MaskLandmark)
        for i in (todo[:1] if shared else todo).tolist():
            solid = DrillSolid(entries[i], dirs[i], radius_mm, tip_length_mm)
            seg = landmark_segments(lm, solid)
            if seg is None:
                return None
            a, b, radii_l[lm_i] = seg
            starts.append(np.asarray(a, dtype=np.float64).reshape(-1, 3))
            ends.append(np.asarray(b, dtype=np.float64).reshape(-1, 3))
            span = (at, at + len(starts[-1]))
            at = span[1]
            if shared:
                ptr[:, lm_i] = span
            else:
                ptr[i, lm_i] = span
    seg_a = np.ascontiguousarray(np.concatenate(starts) if starts else np.empty((0, 3)))
    seg_b = np.ascontiguousarray(np.concatenate(ends) if ends else np.empty((0, 3)))
    clear = np.full((n, d_max, n_l), np.nan)
    safe = np.full((n, 3), np.nan)
    stop = np.full((n, 2), np.nan)
    stop_clear = np.full((n, n_l), np.nan)
    run_spans(
        CLEARANCE_KERNEL,
        row_spans(todo),
        seg_a,
        seg_b,
        ptr,
        radii_l,
        np.ascontiguousarray(margins_mm, dtype=np.float64),
        entries,
        np.ascontiguousarray(dirs),
        np.ascontiguousarray(depth_mm, dtype=np.float64),
        np.ascontiguousarray(n_depths, dtype=np.int64),
        np.ascontiguousarray(planned_mm, dtype=np.float64),
        np.ascontiguousarray(out_of_volume_mm, dtype=np.float64),
        float(radius_mm),
        float(tip_length_mm),
        # the search's constants as data, so a change to them is never hidden by the cache
        np.array(
            [SEGMENT_TOL_MM, SAFE_DEPTH_TOL_MM, SEARCH_BEYOND_PLAN_MM, _REFINE_POINTS],
            dtype=np.float64,
        ),
        clear,
        safe,
        stop,
        stop_clear,
    )
    return ClearanceBatch(
        clearance_mm=clear,
        max_safe_depth_mm=safe[:, 0],
        capped=safe[:, 2] == 1.0,
        binding=np.nan_to_num(safe[:, 1], nan=-1.0).astype(np.int64),
        stop_depth_mm=stop[:, 0],
        stop_reason=np.nan_to_num(stop[:, 1], nan=-1.0).astype(np.int64),
        stop_clearance_mm=stop_clear,
    )
