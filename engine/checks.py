"""The checks before sampling, for every row at once: arguments, points, depth, masks, the
volume edge and slice gaps.

Problems of the arguments or of the volume concern every row and raise once
(:func:`check_arguments`). The others are the row's own (:func:`check_rows`, in this order:
coordinates, planned depth, the masks' grid, a degenerate axis, the entry inside the scan,
slice gaps); a refused row keeps the exception the single path raises, and the rows after it
are checked on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.engine import refusals
from ctdrill.engine.grid import MAX_PLANNED_DEPTH_MM
from ctdrill.imaging.bounds import MAX_COORDINATE_MM
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.landmarks import Landmark, bind_to_grid
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.edge import (
    entry_refusal,
    face_terms,
    lip_exit_depths,
    too_wide_refusal,
    whole_lip_fits,
)
from ctdrill.imaging.sampling.lip import axis_basis, ring_radii_mm
from ctdrill.imaging.sampling.path import (
    PathInputError,
    SliceGap,
    check_volume,
    crossed_gaps,
    require_grid_for_masks,
)
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.errors import ModelInputError

#: Most trajectories one call accepts (memory: a row is ~50 kB at the default grid).
MAX_BATCH = 200_000


@dataclass(frozen=True, eq=False)
class RowChecks:
    """What the checks found, per row.

    Attributes
    ----------
    landmarks : the plan's landmarks bound to the CT grid (masks without their own take it).
    planned_mm : (N,) ``|target - entry|``, mm.
    out_of_volume_mm : (N,) where the lip in contact leaves the scan before the planned depth,
        mm (NaN: it stays inside).
    gaps : per row, the slice gaps the lip reaches into (interpolated when asked; else the
        row is refused).
    errors : per row, None or the refusal (the exception the single path raises).
    """

    landmarks: tuple[Landmark, ...]
    planned_mm: np.ndarray
    out_of_volume_mm: np.ndarray
    gaps: list[tuple[SliceGap, ...]]
    errors: list[Exception | None]

    def ok_rows(self) -> np.ndarray:
        """The rows not refused."""
        return np.array([i for i, e in enumerate(self.errors) if e is None], dtype=np.int64)


def _points(value: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise PathInputError(f"{name}: expected an (N, 3) array of LPS mm, got shape {arr.shape}")
    return arr


def check_arguments(
    volume: CTVolume,
    entries_lps: np.ndarray,
    targets_lps: np.ndarray,
    *,
    depth_step_mm: float,
    n_rings: int,
    n_angles: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The ``(N, 3)`` entries and targets; raise for what concerns every row at once."""
    entries = _points(entries_lps, "entries_lps")
    targets = _points(targets_lps, "targets_lps")
    if entries.shape != targets.shape:
        raise PathInputError(
            f"entries_lps {entries.shape} and targets_lps {targets.shape}: give one target "
            "per entry"
        )
    if entries.shape[0] > MAX_BATCH:
        raise PathInputError(
            f"entries_lps: {entries.shape[0]} trajectories exceed {MAX_BATCH} per call; "
            "evaluate them in several batches"
        )
    if not (math.isfinite(depth_step_mm) and depth_step_mm > 0.0):
        raise refusals.bad_step(depth_step_mm)
    ring_radii_mm(2.0, n_rings)  # refuses a bad count with the sampler's own message
    ring_radii_mm(2.0, n_angles)
    check_volume(volume)
    return entries, targets


def check_rows(
    volume: CTVolume,
    plan: Plan,
    entries: np.ndarray,
    targets: np.ndarray,
    *,
    interpolate_gaps: bool,
) -> RowChecks:
    """Every row's checks before sampling (see the module docstring).

    Parameters
    ----------
    volume : the CT.
    plan : drill, landmarks and name (its own entry and target are not used).
    entries, targets : (N, 3) LPS mm.
    interpolate_gaps : accept slice gaps the lip crosses (they are listed, not refused).
    """
    n = entries.shape[0]
    errors: list[Exception | None] = [None] * n
    planned = np.array(
        [float(np.linalg.norm(t - e)) for e, t in zip(entries, targets, strict=True)]
    )
    lm_ok = all(
        bool(np.all(np.abs(lm.control_points_lps()) <= MAX_COORDINATE_MM)) for lm in plan.landmarks
    )
    with np.errstate(invalid="ignore"):
        coords_ok = np.all(np.abs(entries) <= MAX_COORDINATE_MM, axis=1) & np.all(
            np.abs(targets) <= MAX_COORDINATE_MM, axis=1
        )
    for i in range(n):
        if not (coords_ok[i] and lm_ok):
            errors[i] = refusals.bad_coordinate(plan)
        elif not planned[i] <= MAX_PLANNED_DEPTH_MM:
            errors[i] = refusals.too_deep(plan, float(planned[i]))
    landmarks = plan.landmarks
    try:
        require_grid_for_masks(volume, plan.landmarks, name=plan.name)
        landmarks = bind_to_grid(plan.landmarks, volume.affine_lps, tuple(volume.hu.shape))
    except (ImagingInputError, ModelInputError) as exc:
        errors = [exc if e is None else e for e in errors]
    for i in range(n):
        if errors[i] is None and not planned[i] > 1e-9:
            try:
                axis_basis(entries[i], targets[i])  # its own refusal of a degenerate axis
            except ImagingInputError as exc:
                errors[i] = exc
    oov = np.full(n, np.nan)
    rows = np.array([i for i in range(n) if errors[i] is None], dtype=np.int64)
    terms = face_terms(volume, entries[rows], targets[rows], plan.drill)
    inside, exit_mm = lip_exit_depths(terms)
    fits = whole_lip_fits(terms)
    for j, i in enumerate(rows.tolist()):
        if not inside[j]:
            errors[i] = PathInputError(
                entry_refusal(volume, entries[i], targets[i], plan.drill, name=plan.name)
            )
        elif not fits[j]:
            errors[i] = PathInputError(too_wide_refusal(volume, plan.drill, name=plan.name))
        elif exit_mm[j] < planned[i]:
            oov[i] = exit_mm[j]
    gaps: list[tuple[SliceGap, ...]] = [()] * n
    if volume.has_slice_gaps:
        for i in range(n):
            if errors[i] is not None:
                continue
            end = float(planned[i]) if np.isnan(oov[i]) else float(oov[i])
            gaps[i] = crossed_gaps(volume, entries[i], targets[i], plan.drill, end)
            if gaps[i] and not interpolate_gaps:
                errors[i] = refusals.gap_crossed(plan, gaps[i])
    return RowChecks(landmarks, planned, oov, gaps, errors)
