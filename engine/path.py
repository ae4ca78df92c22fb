"""One trajectory through one CT: lip samples, force profile, clearance, stop depth.

:func:`plan_path` is the single headless entry point used by the export, the rehearsal and the
GUI. It is the one-row case of the engine (:func:`ctdrill.engine.batch.evaluate_rows`), which
refuses (``PathInputError``, exit code 2) what cannot carry a force map safely *on the drill
path*: a single slice, values that are not HU, a slice gap (a step wider than 1.5 nominal
steps) reached by the drill lip unless ``interpolate_gaps`` asks to interpolate across it (then
warning ``gap_interpolated`` and :attr:`PathResult.interpolated_gaps`), padding touched by the
lip in contact, an entry point outside the scanned volume (the part of the drill *behind* the
entry may leave the scan: nothing is cut there; docs/geometry.md). Sampling uses every slice's
true position, so irregular steps narrower than a gap are exact. The warnings of a path are
gathered once (:mod:`ctdrill.engine.path_warnings`), each code + message once.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ctdrill.engine.batch import RowsRun, evaluate_rows
from ctdrill.engine.budget import plan_budgets
from ctdrill.engine.grid import DEFAULT_DEPTH_STEP_MM
from ctdrill.engine.implant import ImplantOutcome, implant_outcome, implant_outcome_with
from ctdrill.engine.path_warnings import path_warnings
from ctdrill.engine.stop import StopReason
from ctdrill.imaging.plan.budget import MarginBudget
from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.annulus import Hole
from ctdrill.imaging.sampling.lip import DEFAULT_N_ANGLES, DEFAULT_N_RINGS, LipSamples
from ctdrill.imaging.sampling.path import PathInputError, SliceGap
from ctdrill.imaging.sampling.walls import start_plan_bone_walls
from ctdrill.imaging.volume import CTVolume, LoadWarning
from ctdrill.model.calibration import Calibration
from ctdrill.model.profile import Profile

__all__ = [
    "PathInputError",
    "PathResult",
    "SliceGap",
    "binding_landmark_doc",
    "complete_path",
    "path_curves",
    "plan_path",
]


@dataclass(frozen=True, eq=False)
class PathResult:
    """Everything computed along one trajectory.

    Attributes
    ----------
    plan : the plan (landmarks bound to the CT grid).
    depth_mm : (D,) uniform depth grid from 0 to the planned depth, mm.
    lip : HU on the cutting lip at each depth.
    profile : force coefficients per depth (``ctdrill.model.Profile``).
    calibration : the calibration set used.
    clearance_mm : (D, L) clearance from the drill to each landmark, mm.
    margins_mm : (L,) margin per landmark, mm.
    max_safe_depth_mm : deepest depth keeping every margin (the search stops at
        ``ctdrill.imaging.plan.safety.search_limit_mm``: see ``max_safe_depth_capped``).
    max_safe_depth_capped : the search reached its limit safely ("safe at least this deep").
    binding_landmark : index of the landmark whose margin sets the max safe depth; when no
        margin binds within the search, the landmark nearest the drill at the stop depth
        (None without landmarks). Export, GUI and rehearsal name this one.
    plan_clearance_mm : smallest signed clearance over the whole planned path (at the planned
        depth: clearance never increases with depth), mm; negative inside a landmark; None
        without landmarks.
    out_of_volume_depth_mm : deepest depth whose lip stays inside the CT, or None if the lip
        stays inside down to the planned depth.
    stop_depth_mm : min(planned, max safe, out of volume), mm.
    stop_reason : :class:`~ctdrill.engine.stop.StopReason` (a ``str``).
    stop_clearance_mm : (L,) clearance at the stop depth, mm.
    warnings : what the user must know (load warnings and path warnings), each code + message
        once.
    interpolated_gaps : slice gaps the lip reaches into that were interpolated across because
        the caller asked to (``interpolate_gaps``); empty otherwise.
    inner_holes : the holes of earlier drills of a sequence the profile cut around (empty for
        a single drill or the first drill of a sequence).
    implant : the implant's outcome (:func:`ctdrill.engine.implant.implant_outcome`: its
        clearance, walls and warnings), or None without an implant (and in a batch's rows,
        which compute the drill only).
    budgets : each landmark's margin budget on this CT (:mod:`ctdrill.engine.budget`; empty
        in a batch's rows).
    """

    plan: Plan
    depth_mm: np.ndarray
    lip: LipSamples
    profile: Profile
    calibration: Calibration
    clearance_mm: np.ndarray
    margins_mm: np.ndarray
    max_safe_depth_mm: float
    max_safe_depth_capped: bool
    binding_landmark: int | None
    plan_clearance_mm: float | None
    out_of_volume_depth_mm: float | None
    stop_depth_mm: float
    stop_reason: StopReason
    stop_clearance_mm: np.ndarray
    warnings: tuple[LoadWarning, ...]
    interpolated_gaps: tuple[SliceGap, ...] = ()
    inner_holes: tuple[Hole, ...] = ()
    implant: ImplantOutcome | None = None
    budgets: tuple[MarginBudget, ...] = ()

    @property
    def planned_depth_mm(self) -> float:
        """``|target - entry|``, mm."""
        return self.plan.planned_depth_mm

    @property
    def landmarks(self) -> tuple[Landmark, ...]:
        """The plan's landmarks (masks bound to the CT grid)."""
        return self.plan.landmarks

    @property
    def min_clearance_mm(self) -> float | None:
        """Smallest clearance to any landmark down to the stop depth, mm (None: no landmark)."""
        if self.stop_clearance_mm.size == 0:
            return None
        return float(self.stop_clearance_mm.min())

    @property
    def binding_margin_mm(self) -> float:
        """The margin of :attr:`binding_landmark` (the plan's margin without landmarks), mm."""
        if self.binding_landmark is None:
            return float(self.plan.margin_mm)
        return float(self.margins_mm[self.binding_landmark])

    @property
    def min_clearance_per_depth_mm(self) -> np.ndarray:
        """(D,) clearance to the nearest landmark at each depth, mm (inf without landmarks)."""
        if self.clearance_mm.shape[1] == 0:
            return np.full(self.depth_mm.shape, np.inf)
        out: np.ndarray = self.clearance_mm.min(axis=1)
        return out


def binding_landmark_doc(result: PathResult) -> dict[str, object] | None:
    """The binding landmark as summaries name it: ``name``, ``kind``, ``margin_mm`` and the
    ``clearance_at_stop_mm`` (None without landmarks)."""
    j = result.binding_landmark
    if j is None:
        return None
    lm = result.landmarks[j]
    return {
        "name": lm.name,
        "kind": lm.kind,
        "margin_mm": float(result.margins_mm[j]),
        "clearance_at_stop_mm": round(float(result.stop_clearance_mm[j]), 4),
    }


def plan_path(
    volume: CTVolume,
    plan: Plan,
    calibration: Calibration,
    *,
    depth_step_mm: float = DEFAULT_DEPTH_STEP_MM,
    n_rings: int = DEFAULT_N_RINGS,
    n_angles: int = DEFAULT_N_ANGLES,
    interpolate_gaps: bool = False,
    inner_holes: Sequence[Hole] = (),
    implant: ImplantOutcome | None = None,
) -> PathResult:
    """Sample the CT along ``plan``, build the force profile, the clearances and the stop.

    Parameters
    ----------
    volume : the CT (LPS).
    plan : trajectory, drill and landmarks (mask landmarks without a grid take the CT's).
    calibration : force-law coefficients.
    depth_step_mm : profile depth step, mm (the grid is uniform from 0 to the planned depth).
    n_rings, n_angles : lip discretisation (defaults measured in bench/bench_sampling.py).
    interpolate_gaps : interpolate across slice gaps the lip reaches into instead of refusing
        (the result says so: warning ``gap_interpolated``, ``interpolated_gaps``).
    inner_holes : holes left along this axis by the earlier, narrower drills of a sequence
        (:mod:`ctdrill.imaging.sampling.annulus`): the force counts only the lip outside them.
        Clearance, stop and the volume checks are this drill's own, on its whole solid. Empty
        (a single drill): the full lip, exactly as before. :mod:`ctdrill.engine.sequence` runs
        a whole sequence.
    implant : the plan's implant outcome when already computed (a sequence computes it once
        for all its drills); else computed here for a plan with an implant.

    Returns
    -------
    PathResult

    Raises
    ------
    PathInputError
        When the CT cannot carry a force map along the path (see the module docstring).
    """
    # the implant's bone walls start on the worker threads (compiled rays, no interpreter
    # lock) while this thread computes the drill's path, then lends itself to the rays left
    walls = start_plan_bone_walls(volume, plan) if implant is None else None
    try:
        result = path_curves(
            volume,
            plan,
            calibration,
            depth_step_mm=depth_step_mm,
            n_rings=n_rings,
            n_angles=n_angles,
            interpolate_gaps=interpolate_gaps,
            inner_holes=inner_holes,
        )
    except BaseException:
        if walls is not None:
            with contextlib.suppress(Exception):
                walls()  # no rays left running behind a refusal
        raise
    if walls is not None:
        implant = implant_outcome_with(volume, result.plan, walls)
    return complete_path(volume, result, implant)


def path_curves(
    volume: CTVolume,
    plan: Plan,
    calibration: Calibration,
    *,
    depth_step_mm: float = DEFAULT_DEPTH_STEP_MM,
    n_rings: int = DEFAULT_N_RINGS,
    n_angles: int = DEFAULT_N_ANGLES,
    interpolate_gaps: bool = False,
    inner_holes: Sequence[Hole] = (),
) -> PathResult:
    """The first part of :func:`plan_path` (same arguments): the lip, the force profile, the
    clearances and the stop, exactly as :func:`plan_path` gives them, without the implant's
    outcome, the budgets and the warnings (:func:`complete_path` adds them). A window shows
    these curves while the rest is computed.

    Raises
    ------
    PathInputError
        As :func:`plan_path`.
    """
    run = evaluate_rows(
        volume,
        plan,
        plan.entry_lps[None, :],
        plan.target_lps[None, :],
        calibration,
        depth_step_mm=depth_step_mm,
        n_rings=n_rings,
        n_angles=n_angles,
        interpolate_gaps=interpolate_gaps,
        holes=tuple(inner_holes),
        keep_lips=True,
    )
    if run.errors[0] is not None:
        raise run.errors[0]
    return path_row(
        run, 0, calibration, interpolate_gaps=interpolate_gaps, inner_holes=tuple(inner_holes)
    )


def complete_path(
    volume: CTVolume, result: PathResult, implant: ImplantOutcome | None = None
) -> PathResult:
    """``result`` of :func:`path_curves` completed as :func:`plan_path` returns it: the
    implant's outcome (``implant``, else computed here for a plan with an implant), the
    margin budgets and the warnings."""
    plan = result.plan
    if implant is None and plan.implant is not None:
        implant = implant_outcome(volume, result.plan)
    result = replace(result, implant=implant, budgets=plan_budgets(volume, result.plan))
    return replace(result, warnings=path_warnings(volume, result))


def path_row(
    run: RowsRun,
    index: int,
    calibration: Calibration,
    *,
    interpolate_gaps: bool,
    inner_holes: tuple[Hole, ...] = (),
) -> PathResult:
    """Row ``index`` of ``run`` (computed with its lip kept) as a :class:`PathResult`, without
    its warnings (:func:`~ctdrill.engine.path_warnings.path_warnings` gives them)."""
    b = run.batch
    i = index
    m = int(b.n_depths[i])
    depth = b.depth_mm[i, :m]
    plan = run.plan
    if not np.array_equal(plan.entry_lps, b.entries_lps[i]) or not np.array_equal(
        plan.target_lps, b.targets_lps[i]
    ):
        plan = b.plan_for(plan, i)
    profile = Profile(
        depth_mm=depth,
        s0_n=b.s0_n[i, :m],
        sk_n=b.sk_n[i, :, :m],
        freqs_hz=b.freqs_hz,
        s_t=b.s_t[i, :m],
        hu_mean=b.hu_mean[i, :m],
        ke_per_mm_s=b.ke_per_mm_s,
        n_clipped=int(b.n_clipped[i]),
        n_samples=int(b.n_samples[i]),
        calibration=calibration.name,
    )
    binding = int(b.binding_landmark[i])
    oov = float(b.out_of_volume_depth_mm[i])
    plan_clear = float(b.plan_clearance_mm[i])
    return PathResult(
        plan=plan,
        depth_mm=depth,
        lip=run.lips[i],
        profile=profile,
        calibration=calibration,
        clearance_mm=b.clearance_mm[i, :m],
        margins_mm=b.margins_mm,
        max_safe_depth_mm=float(b.max_safe_depth_mm[i]),
        max_safe_depth_capped=bool(b.max_safe_depth_capped[i]),
        binding_landmark=None if binding < 0 else binding,
        plan_clearance_mm=None if np.isnan(plan_clear) else plan_clear,
        out_of_volume_depth_mm=None if np.isnan(oov) else oov,
        stop_depth_mm=float(b.stop_depth_mm[i]),
        stop_reason=StopReason(b.stop_reason[i]),
        stop_clearance_mm=b.stop_clearance_mm[i],
        warnings=(),
        interpolated_gaps=run.gaps[i] if interpolate_gaps else (),
        inner_holes=inner_holes,
    )
