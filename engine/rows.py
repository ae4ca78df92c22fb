"""``plan_path``'s per-trajectory steps for :func:`ctdrill.engine.batch.evaluate_batch`:
the checks before sampling (with the same refusal messages) and the clearance path used when
the compiled kernel is not available."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ctdrill.engine.path import (
    MAX_COORDINATE_MM,
    MAX_PLANNED_DEPTH_MM,
    grid_bracket,
)
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.clearance_batch import ClearanceBatch
from ctdrill.imaging.plan.landmarks import Landmark, bind_to_grid
from ctdrill.imaging.plan.safety import clearance_profile_mm, margins_mm, safe_depth
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.lip_batch import lip_inside_depths
from ctdrill.imaging.sampling.path import (
    crossed_gaps,
    out_of_volume_depth_mm,
    require_grid_for_masks,
)
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.errors import ModelInputError


def row_checks(
    volume: CTVolume,
    plan: Plan,
    entries: np.ndarray,
    targets: np.ndarray,
    planned: np.ndarray,
    refusal: list[str | None],
) -> tuple[tuple[Landmark, ...], np.ndarray]:
    """``plan_path``'s checks before sampling, in its order, row by row where they depend on
    the row: coordinates, planned depth, the masks' grid, the entry inside the scan (and the
    out-of-volume depth, NaN for none). Fills ``refusal``; returns the bound landmarks."""
    n = entries.shape[0]
    lm_coords = [lm.control_points_lps() for lm in plan.landmarks]
    lm_ok = all(bool(np.all(np.abs(c) <= MAX_COORDINATE_MM)) for c in lm_coords)
    with np.errstate(invalid="ignore"):
        coords_ok = np.all(np.abs(entries) <= MAX_COORDINATE_MM, axis=1) & np.all(
            np.abs(targets) <= MAX_COORDINATE_MM, axis=1
        )
    for i in range(n):
        if not (coords_ok[i] and lm_ok):
            refusal[i] = (
                f"plan {plan.name!r}: a coordinate is not finite or beyond "
                f"{MAX_COORDINATE_MM:g} mm; check the plan's points (units are mm)"
            )
        elif not planned[i] <= MAX_PLANNED_DEPTH_MM:
            refusal[i] = (
                f"plan {plan.name!r}: planned depth {planned[i]:.6g} mm exceeds "
                f"{MAX_PLANNED_DEPTH_MM:g} mm; check the entry and target (units are mm)"
            )
    landmarks = plan.landmarks
    try:
        require_grid_for_masks(volume, plan.landmarks, name=plan.name)
        landmarks = bind_to_grid(plan.landmarks, volume.affine_lps, tuple(volume.hu.shape))
    except (ImagingInputError, ModelInputError) as exc:
        for i in range(n):
            if refusal[i] is None:
                refusal[i] = str(exc)
    oov = np.full(n, np.nan)
    rows = np.array([i for i in range(n) if refusal[i] is None], dtype=np.int64)
    degenerate = planned[rows] <= 1e-9
    lo, hi = lip_inside_depths(volume, entries[rows], targets[rows], plan.drill)
    for j, i in enumerate(rows.tolist()):
        # entry near the edge of the scan, the lip's end near the planned depth, or a
        # degenerate axis: the per-row function decides (and words the refusal); elsewhere
        # the batched closed form is the same number
        near = abs(hi[j] - planned[i]) < 1e-6
        if degenerate[j] or near or not (lo[j] + 1e-6 < 0.0 < hi[j] - 1e-6):
            try:
                end = out_of_volume_depth_mm(
                    volume, entries[i], targets[i], plan.drill, float(planned[i]), name=plan.name
                )
            except (ImagingInputError, ModelInputError) as exc:
                refusal[i] = str(exc)
                continue
            oov[i] = np.nan if end is None else end
        elif hi[j] < planned[i]:
            oov[i] = hi[j]
    return landmarks, oov


def gap_checks(
    volume: CTVolume,
    plan: Plan,
    entries: np.ndarray,
    targets: np.ndarray,
    planned: np.ndarray,
    oov: np.ndarray,
    refusal: list[str | None],
    interpolate_gaps: bool,
) -> None:
    """Refuse rows whose lip crosses a slice gap (``plan_path``'s message), unless asked."""
    if interpolate_gaps:
        return
    for i, (e, t) in enumerate(zip(entries, targets, strict=True)):
        if refusal[i] is not None:
            continue
        end = float(planned[i]) if np.isnan(oov[i]) else float(oov[i])
        gaps = crossed_gaps(volume, e, t, plan.drill, end)
        if gaps:
            refusal[i] = (
                f"plan {plan.name!r}: the drill lip crosses "
                + (f"{len(gaps)} slice gaps, the first: " if len(gaps) > 1 else "")
                + f"{gaps[0].describe()}; the CT holds no "
                "slice there: plan away from it, or interpolate across it explicitly "
                "(--interpolate-gaps; the summary then says so)"
            )


def clearances_each(
    plan: Plan,
    entries: np.ndarray,
    targets: np.ndarray,
    depth: np.ndarray,
    n_dep: np.ndarray,
    oov: np.ndarray,
    rows: np.ndarray,
) -> ClearanceBatch:
    """``plan_path``'s clearance, safe depth and stop, row by row (no compiled kernel)."""
    n, d_max = depth.shape
    n_l = len(plan.landmarks)
    out = ClearanceBatch(
        clearance_mm=np.full((n, d_max, n_l), np.nan),
        max_safe_depth_mm=np.full(n, np.nan),
        capped=np.zeros(n, dtype=bool),
        binding=np.full(n, -1, dtype=np.int64),
        stop_depth_mm=np.full(n, np.nan),
        stop_reason=np.full(n, -1, dtype=np.int64),
        stop_clearance_mm=np.full((n, n_l), np.nan),
    )
    margins = margins_mm(plan)
    for i in rows.tolist():
        row = replace(plan, entry_lps=entries[i], target_lps=targets[i])
        m = int(n_dep[i])
        clearance = clearance_profile_mm(row, row.landmarks, depth[i, :m])
        safe = safe_depth(row, bracket_mm=grid_bracket(depth[i, :m], clearance, margins))
        stops = [row.planned_depth_mm, safe.depth_mm, float(oov[i])]
        code = min(range(3), key=lambda c: stops[c])  # ties: first listed wins
        stop_clear = clearance_profile_mm(row, row.landmarks, np.array([stops[code]]))[0]
        binding = safe.binding
        if binding is None and n_l:
            binding = int(np.argmin(stop_clear))
        out.clearance_mm[i, :m] = clearance
        out.max_safe_depth_mm[i] = safe.depth_mm
        out.capped[i] = safe.capped
        out.binding[i] = -1 if binding is None else binding
        out.stop_depth_mm[i] = stops[code]
        out.stop_reason[i] = code
        out.stop_clearance_mm[i] = stop_clear
    return out
