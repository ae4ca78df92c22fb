"""One trajectory through one CT: lip samples, force profile, clearance, stop depth.

:func:`plan_path` is the single headless entry point used by the export, the rehearsal and the
GUI. It orchestrates; the volume-side checks live in :mod:`ctdrill.imaging.sampling.path` and refuse
(``PathInputError``, exit code 2) a volume that cannot carry a force map safely *on the drill
path*: a single slice, values that are not HU, a slice gap (a step wider than 1.5 nominal
steps) reached by the drill lip unless ``interpolate_gaps`` asks to interpolate across it (then
warning ``gap_interpolated`` and :attr:`PathResult.interpolated_gaps`), padding touched by the
drill, an entry point outside the scanned volume. Sampling uses every slice's true position, so
irregular steps narrower than a gap are exact. The warnings of a path are gathered here once,
each code + message once.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ctdrill.imaging.plan.implant_checks import implant_warnings, implants_too_close
from ctdrill.imaging.plan.landmarks import Landmark, bind_to_grid
from ctdrill.imaging.plan.safety import (
    clearance_profile_mm,
    margin_warnings,
    margins_mm,
    safe_depth,
)
from ctdrill.imaging.plan.types import Plan, plan_warnings, series_uid_hash
from ctdrill.imaging.sampling.annulus import Hole, holes_on_grid
from ctdrill.imaging.sampling.lip import (
    DEFAULT_N_ANGLES,
    DEFAULT_N_RINGS,
    LipSamples,
    sample_lip_rings,
)
from ctdrill.imaging.sampling.path import (
    PathInputError,
    SliceGap,
    check_padding,
    check_volume,
    crossed_gaps,
    out_of_volume_depth_mm,
    require_grid_for_masks,
)
from ctdrill.imaging.volume import CTVolume, LoadWarning
from ctdrill.model.calibration import Calibration, load_calibration
from ctdrill.model.force import feed_outside_model
from ctdrill.model.profile import Profile, build_profile

#: Default depth step of the profile, mm: trilinear sampling is converged at 0.05 mm on
#: 0.3 mm voxels (DESIGN.md section 6); steps above a third of a voxel add error.
DEFAULT_DEPTH_STEP_MM = 0.05
#: Longest trajectory accepted, mm: far beyond any dental drill, short enough to bound memory.
MAX_PLANNED_DEPTH_MM = 200.0

#: Largest coordinate magnitude accepted in a plan, mm (the plan reader's bound).
MAX_COORDINATE_MM = 1e5

STOP_REASONS = ("planned_depth", "margin", "out_of_volume")


__all__ = [
    "PathInputError",
    "PathResult",
    "SliceGap",
    "dedupe_warnings",
    "depth_grid_mm",
    "plan_calibration",
    "plan_calibration_key",
    "plan_path",
    "with_set_warnings",
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
    stop_reason : ``planned_depth`` | ``margin`` | ``out_of_volume``.
    stop_clearance_mm : (L,) clearance at the stop depth, mm.
    warnings : what the user must know (load warnings and path warnings), each code + message
        once.
    interpolated_gaps : slice gaps the lip reaches into that were interpolated across because
        the caller asked to (``interpolate_gaps``); empty otherwise.
    inner_holes : the holes of earlier drills of a sequence the profile cut around (empty for
        a single drill or the first drill of a sequence).
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
    stop_reason: str
    stop_clearance_mm: np.ndarray
    warnings: tuple[LoadWarning, ...]
    interpolated_gaps: tuple[SliceGap, ...] = ()
    inner_holes: tuple[Hole, ...] = ()

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


def with_set_warnings(plans: Sequence[Plan]) -> tuple[Plan, ...]:
    """``plans`` each carrying the warnings only the whole set shows (``implants_too_close``,
    :func:`~ctdrill.imaging.plan.implant_checks.implants_too_close`) in ``Plan.warnings``, so
    that :func:`plan_path` reports them with the rest; call it where a command sees every
    trajectory of a plan set, after its last edit."""
    seq = tuple(plans)
    extra = implants_too_close(seq)
    return tuple(
        replace(p, warnings=(*p.warnings, *extra[p.name])) if p.name in extra else p for p in seq
    )


def depth_grid_mm(planned_depth_mm: float, step_mm: float) -> np.ndarray:
    """(D,) uniform depths from 0 to ``planned_depth_mm`` with a step <= ``step_mm``."""
    n = max(2, math.ceil(planned_depth_mm / step_mm - 1e-9) + 1)
    return np.linspace(0.0, planned_depth_mm, n)


def dedupe_warnings(warnings: list[LoadWarning]) -> tuple[LoadWarning, ...]:
    """``warnings`` in order, each (code, message) once."""
    seen: set[tuple[str, str]] = set()
    out: list[LoadWarning] = []
    for w in warnings:
        if (w.code, w.message) not in seen:
            seen.add((w.code, w.message))
            out.append(w)
    return tuple(out)


def grid_bracket(
    depth: np.ndarray, clearance: np.ndarray, margins: np.ndarray
) -> tuple[float, float] | None:
    """The grid step where the margin is first violated (max_safe_depth_mm checks it)."""
    if clearance.shape[1] == 0:
        return None
    bad = np.flatnonzero(np.any(clearance < margins[None, :], axis=1))
    if bad.size == 0 or bad[0] == 0:
        return None
    return float(depth[bad[0] - 1]), float(depth[bad[0]])


def plan_calibration_key(plan: Plan) -> str:
    """What to pass to :func:`ctdrill.model.load_calibration` for the plan's set: a bundled name as
    written, a path relative to the plan file resolved beside it."""
    key = plan.calibration
    candidate = Path(key)
    if plan.source and not candidate.is_absolute() and ("/" in key or key.endswith(".json")):
        beside = Path(plan.source).parent / candidate
        if beside.is_file():
            key = str(beside)
    return key


def plan_calibration(plan: Plan) -> Calibration:
    """The plan's calibration set (see :func:`plan_calibration_key`).

    Raises
    ------
    model.calibration.CalibrationError
        The set is missing or invalid (the message names the file and field).
    """
    return load_calibration(plan_calibration_key(plan))


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
        (a single drill): the full lip, exactly as before. :mod:`ctdrill.engine.sequence` runs a
        whole sequence.

    Returns
    -------
    PathResult

    Raises
    ------
    PathInputError
        When the CT cannot carry a force map along the path (see the module docstring).
    """
    if not (math.isfinite(depth_step_mm) and depth_step_mm > 0.0):
        raise PathInputError(f"depth_step_mm must be a positive number, got {depth_step_mm!r}")
    coords = [plan.entry_lps, plan.target_lps]
    coords += [lm.control_points_lps() for lm in plan.landmarks]
    if not all(np.all(np.abs(c) <= MAX_COORDINATE_MM) for c in coords):
        raise PathInputError(
            f"plan {plan.name!r}: a coordinate is not finite or beyond {MAX_COORDINATE_MM:g} mm; "
            "check the plan's points (units are mm)"
        )
    if not plan.planned_depth_mm <= MAX_PLANNED_DEPTH_MM:
        raise PathInputError(
            f"plan {plan.name!r}: planned depth {plan.planned_depth_mm:.6g} mm exceeds "
            f"{MAX_PLANNED_DEPTH_MM:g} mm; check the entry and target (units are mm)"
        )
    check_volume(volume)
    require_grid_for_masks(volume, plan.landmarks, name=plan.name)
    landmarks = bind_to_grid(plan.landmarks, volume.affine_lps, tuple(volume.hu.shape))
    plan = replace(plan, landmarks=landmarks)
    depth = depth_grid_mm(plan.planned_depth_mm, depth_step_mm)
    entry, target, drill = plan.entry_lps, plan.target_lps, plan.drill
    oov = out_of_volume_depth_mm(
        volume, entry, target, drill, plan.planned_depth_mm, name=plan.name
    )
    gaps = crossed_gaps(volume, entry, target, drill, plan.planned_depth_mm if oov is None else oov)
    if gaps and not interpolate_gaps:
        raise PathInputError(
            f"plan {plan.name!r}: the drill lip crosses "
            + (f"{len(gaps)} slice gaps, the first: " if len(gaps) > 1 else "")
            + f"{gaps[0].describe()}; the CT holds no "
            "slice there: plan away from it, or interpolate across it explicitly "
            "(--interpolate-gaps; the summary then says so)"
        )
    warnings = list(volume.warnings)
    warnings += [LoadWarning(code, message) for code, message in plan_warnings(plan)]
    warnings += [
        LoadWarning(
            "gap_interpolated",
            f"plan {plan.name!r}: the drill lip crosses {gap.describe()}; HU there are "
            "interpolated linearly between the two real slices, as asked",
        )
        for gap in gaps
    ]
    holes = tuple(inner_holes)
    on_grid = holes_on_grid(holes, depth)
    lip = sample_lip_rings(
        volume, entry, target, depth, drill, n_rings=n_rings, n_angles=n_angles, holes=on_grid
    )
    check_padding(
        volume, entry, target, drill, lip, n_rings, n_angles, name=plan.name, holes=on_grid
    )
    profile = build_profile(
        lip.hu, lip.ring_weights, depth, calibration, blades=plan.drill.blades, rpm=plan.drill.rpm
    )
    clearance = clearance_profile_mm(plan, plan.landmarks, depth)
    margins = margins_mm(plan)
    safe = safe_depth(plan, bracket_mm=grid_bracket(depth, clearance, margins))
    max_safe = safe.depth_mm
    candidates = [
        (plan.planned_depth_mm, "planned_depth"),
        (max_safe, "margin"),
        (math.inf if oov is None else oov, "out_of_volume"),
    ]
    stop_depth, stop_reason = min(candidates, key=lambda c: c[0])  # ties: first listed wins
    stop_clearance = clearance_profile_mm(plan, plan.landmarks, np.array([stop_depth]))[0]
    binding = safe.binding
    if binding is None and plan.landmarks:
        binding = int(np.argmin(stop_clearance))
    plan_clearance = clearance[-1] if plan.landmarks else np.empty(0)
    warnings += [
        LoadWarning(code, msg) for code, msg in margin_warnings(plan, plan_clearance, margins)
    ]
    if plan.series_uid_sha256 is not None and plan.series_uid_sha256 != series_uid_hash(
        volume.info.series_uid
    ):
        warnings.append(
            LoadWarning(
                "plan_other_series",
                f"plan {plan.name!r} was made on another series than the one loaded (its "
                "recorded series hash differs): check that the CT and the plan belong together",
            )
        )
    if calibration.illustrative:
        warnings.append(
            LoadWarning(
                "calibration_illustrative",
                f"calibration {calibration.name!r} is illustrative (not measured on bone): "
                "forces show the pattern, not validated magnitudes",
            )
        )
    feed_note = feed_outside_model(plan.feed_mm_s, calibration)
    if feed_note is not None:
        warnings.append(LoadWarning("feed_outside_model", f"plan {plan.name!r}: {feed_note}"))
    if profile.n_clipped:
        warnings.append(
            LoadWarning(
                "extrapolated",
                f"{profile.n_clipped} of {profile.n_samples} cut lip samples lie outside the "
                f"calibration's C' range {list(calibration.c_prime_range)}; clipped to it",
            )
        )
    warnings += [
        LoadWarning(code, msg)
        for code, msg in implant_warnings(plan, float(stop_depth), stop_reason)
    ]
    if stop_reason == "out_of_volume":
        warnings.append(
            LoadWarning(
                "out_of_volume",
                f"plan {plan.name!r}: the drill leaves the CT volume at {stop_depth:.3f} mm, "
                f"before the planned depth {plan.planned_depth_mm:.3f} mm",
            )
        )
    return PathResult(
        plan=plan,
        depth_mm=depth,
        lip=lip,
        profile=profile,
        calibration=calibration,
        clearance_mm=clearance,
        margins_mm=margins,
        max_safe_depth_mm=max_safe,
        max_safe_depth_capped=safe.capped,
        binding_landmark=binding,
        plan_clearance_mm=float(plan_clearance.min()) if plan_clearance.size else None,
        out_of_volume_depth_mm=oov,
        stop_depth_mm=float(stop_depth),
        stop_reason=stop_reason,
        stop_clearance_mm=stop_clearance,
        warnings=dedupe_warnings(warnings),
        interpolated_gaps=gaps if interpolate_gaps else (),
        inner_holes=holes,
    )
