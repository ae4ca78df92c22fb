"""One trajectory through one CT: lip samples, force profile, clearance, stop depth.

:func:`plan_path` is the single headless entry point used by the export, the rehearsal and the
GUI. It refuses (``PathInputError``, exit code 2) a volume that cannot carry a force map
safely *on the drill path*: a single slice, values that are not HU, a slice gap or a
non-uniform slice step crossed by the drill, padding touched by the drill, an entry point
outside the scanned volume. The same defects away from the path become warnings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.imaging.plan.landmarks import CanalLandmark, Landmark, PointLandmark, bind_to_grid
from ctdrill.imaging.plan.safety import clearance_profile_mm, max_safe_depth_mm
from ctdrill.imaging.plan.types import Plan, plan_warnings
from ctdrill.imaging.sampling.lip import (
    DEFAULT_N_ANGLES,
    DEFAULT_N_RINGS,
    LipSamples,
    lip_ring_points,
    sample_lip_rings,
)
from ctdrill.imaging.volume import CTVolume, LoadWarning
from ctdrill.model.calibration import Calibration, load_calibration
from ctdrill.model.profile import Profile, build_profile

#: Default depth step of the profile, mm: trilinear sampling is converged at 0.05 mm on
#: 0.3 mm voxels (DESIGN.md section 6); steps above a third of a voxel add error.
DEFAULT_DEPTH_STEP_MM = 0.05
#: Relative tolerance on a slice step before it counts as irregular.
SLICE_STEP_RTOL = 0.01
#: Precision of the out-of-volume depth, mm.
_OOV_TOL_MM = 1e-3

#: Longest trajectory accepted, mm: far beyond any dental drill, short enough to bound memory.
MAX_PLANNED_DEPTH_MM = 200.0

#: Largest coordinate magnitude accepted in a plan, mm (the plan reader's bound).
MAX_COORDINATE_MM = 1e5

STOP_REASONS = ("planned_depth", "margin", "out_of_volume")


class PathInputError(AppInputError):
    """The volume cannot carry a force map safely along this plan's drill path."""


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
    max_safe_depth_mm : deepest depth keeping every margin (capped at planned + 10 mm).
    out_of_volume_depth_mm : deepest depth whose lip stays inside the CT, or None if the lip
        stays inside down to the planned depth.
    stop_depth_mm : min(planned, max safe, out of volume), mm.
    stop_reason : ``planned_depth`` | ``margin`` | ``out_of_volume``.
    stop_clearance_mm : (L,) clearance at the stop depth, mm.
    warnings : what the user must know (load warnings and path warnings).
    """

    plan: Plan
    depth_mm: np.ndarray
    lip: LipSamples
    profile: Profile
    calibration: Calibration
    clearance_mm: np.ndarray
    margins_mm: np.ndarray
    max_safe_depth_mm: float
    out_of_volume_depth_mm: float | None
    stop_depth_mm: float
    stop_reason: str
    stop_clearance_mm: np.ndarray
    warnings: tuple[LoadWarning, ...]

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
    def nearest_landmark(self) -> int | None:
        """Index of the landmark closest to the drill at the stop depth (None: no landmark)."""
        if self.stop_clearance_mm.size == 0:
            return None
        return int(np.argmin(self.stop_clearance_mm))

    @property
    def min_clearance_per_depth_mm(self) -> np.ndarray:
        """(D,) clearance to the nearest landmark at each depth, mm (inf without landmarks)."""
        if self.clearance_mm.shape[1] == 0:
            return np.full(self.depth_mm.shape, np.inf)
        out: np.ndarray = self.clearance_mm.min(axis=1)
        return out


def depth_grid_mm(planned_depth_mm: float, step_mm: float) -> np.ndarray:
    """(D,) uniform depths from 0 to ``planned_depth_mm`` with a step <= ``step_mm``."""
    n = max(2, math.ceil(planned_depth_mm / step_mm - 1e-9) + 1)
    return np.linspace(0.0, planned_depth_mm, n)


def _irregular_steps(volume: CTVolume) -> np.ndarray:
    """(S-1,) bool: the step between slice k and k+1 differs from the median by > 1 %."""
    pos = np.asarray(volume.slice_positions_mm, dtype=np.float64)
    if pos.size < 2:
        return np.zeros(0, dtype=bool)
    steps = np.diff(pos)
    med = float(np.median(steps))
    out: np.ndarray = np.abs(steps - med) > SLICE_STEP_RTOL * abs(med)
    return out


def _check_volume(volume: CTVolume, plan: Plan, end_points: np.ndarray) -> list[LoadWarning]:
    """Refuse what cannot carry a force map on the path; return warnings for the rest.

    ``end_points`` are the lip samples at the first and last depth: the slice index is affine
    in position, so the extremes of every lip sample's slice index are among them.
    """
    where = f"plan {plan.name!r}"
    if not volume.is_volume:
        raise PathInputError(
            f"series {volume.info.series_uid}: a single slice is not a volume; the force "
            "along a drill needs a CT series of several slices"
        )
    if not volume.info.is_hu:
        raise PathInputError(
            f"series {volume.info.series_uid}: voxel values are not Hounsfield units "
            f"(RescaleType {volume.info.rescale_type or 'missing'}); calibrate the grey values "
            "to HU before computing forces"
        )
    warnings: list[LoadWarning] = []
    irregular = _irregular_steps(volume)
    if irregular.any():
        ks = volume.lps_to_index(end_points.reshape(-1, 3))[:, 2]
        k_lo, k_hi = math.floor(float(ks.min())), math.ceil(float(ks.max()))
        crossed = [k for k in np.flatnonzero(irregular) if k_lo - 1 <= k <= k_hi]
        if crossed:
            pos = volume.slice_positions_mm
            k = int(crossed[0])
            raise PathInputError(
                f"{where}: the drill path crosses an irregular slice step "
                f"({pos[k]:.2f} -> {pos[k + 1]:.2f} mm, median step "
                f"{float(np.median(np.diff(pos))):.2f} mm: a slice gap or non-uniform "
                "spacing); resample the series to uniform slices or plan away from it"
            )
        warnings.append(
            LoadWarning(
                "nonuniform_spacing",
                f"{where}: {int(irregular.sum())} irregular slice step(s) away from the drill "
                "path (not used)",
            )
        )
    return warnings


def _check_padding(
    volume: CTVolume, plan: Plan, lip: LipSamples, n_rings: int, n_angles: int
) -> None:
    """Refuse a path whose lip samples touch padding inside the grid (only depths where the
    sampler counted samples outside or on padding are looked at again)."""
    flagged = np.flatnonzero(lip.outside > 0)
    if volume.valid is None or flagged.size == 0:
        return
    points = lip_ring_points(
        plan.entry_lps,
        plan.target_lps,
        lip.depth_mm[flagged],
        diameter_mm=plan.drill.diameter_mm,
        tip_length_mm=plan.drill.tip_length_mm,
        n_rings=n_rings,
        n_angles=n_angles,
    ).reshape(-1, 3)
    idx = volume.lps_to_index(points)
    n_s, n_r, n_c = volume.hu.shape
    sizes = np.array([n_c, n_r, n_s], dtype=np.float64)
    in_grid = np.all((idx >= -1e-6) & (idx <= sizes - 1.0 + 1e-6), axis=1)
    on_padding = in_grid & ~volume.inside(points)
    if on_padding.any():
        raise PathInputError(
            f"plan {plan.name!r}: the drill path crosses padding (pixels outside the scanner's "
            f"reconstruction field, {int(on_padding.sum())} lip samples); the CT holds no "
            "data there: move the trajectory into the reconstructed field"
        )


def _out_of_volume_depth_mm(
    volume: CTVolume, plan: Plan, lip: LipSamples, n_rings: int, n_angles: int
) -> float | None:
    """Deepest depth whose lip samples all lie inside the volume (None: never leaves)."""
    bad = np.flatnonzero(lip.outside > 0)
    if bad.size == 0:
        return None
    first = int(bad[0])
    if first == 0:
        raise PathInputError(
            f"plan {plan.name!r}: the entry point {np.round(plan.entry_lps, 2).tolist()} (LPS "
            "mm) lies outside the CT volume (the drill lip is not inside the scan at depth 0); "
            "move the entry inside the scanned field"
        )
    lo, hi = float(lip.depth_mm[first - 1]), float(lip.depth_mm[first])

    def fully_inside(x: float) -> bool:
        pts = lip_ring_points(
            plan.entry_lps,
            plan.target_lps,
            np.array([x]),
            diameter_mm=plan.drill.diameter_mm,
            tip_length_mm=plan.drill.tip_length_mm,
            n_rings=n_rings,
            n_angles=n_angles,
        )
        return bool(np.all(volume.inside(pts.reshape(-1, 3))))

    while hi - lo > _OOV_TOL_MM:
        mid = 0.5 * (lo + hi)
        if fully_inside(mid):
            lo = mid
        else:
            hi = mid
    return lo


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
) -> PathResult:
    """Sample the CT along ``plan``, build the force profile, the clearances and the stop.

    Parameters
    ----------
    volume : the CT (LPS).
    plan : trajectory, drill and landmarks (mask landmarks without a grid take the CT's).
    calibration : force-law coefficients.
    depth_step_mm : profile depth step, mm (the grid is uniform from 0 to the planned depth).
    n_rings, n_angles : lip discretisation (defaults measured in bench/bench_sampling.py).

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
    coords += [lm.points_lps for lm in plan.landmarks if isinstance(lm, CanalLandmark)]
    coords += [lm.point_lps for lm in plan.landmarks if isinstance(lm, PointLandmark)]
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
    landmarks = bind_to_grid(plan.landmarks, volume.affine_lps, tuple(volume.hu.shape))
    plan = replace(plan, landmarks=landmarks)
    depth = depth_grid_mm(plan.planned_depth_mm, depth_step_mm)
    end_points = lip_ring_points(
        plan.entry_lps,
        plan.target_lps,
        depth[[0, -1]],
        diameter_mm=plan.drill.diameter_mm,
        tip_length_mm=plan.drill.tip_length_mm,
        n_rings=n_rings,
        n_angles=n_angles,
    )
    warnings = list(volume.warnings)
    warnings += [LoadWarning(code, message) for code, message in plan_warnings(plan)]
    warnings += _check_volume(volume, plan, end_points)
    lip = sample_lip_rings(
        volume,
        plan.entry_lps,
        plan.target_lps,
        depth,
        diameter_mm=plan.drill.diameter_mm,
        tip_length_mm=plan.drill.tip_length_mm,
        n_rings=n_rings,
        n_angles=n_angles,
    )
    _check_padding(volume, plan, lip, n_rings, n_angles)
    profile = build_profile(
        lip.hu, lip.ring_weights, depth, calibration, blades=plan.drill.blades, rpm=plan.drill.rpm
    )
    clearance = clearance_profile_mm(plan, plan.landmarks, depth)
    margins = np.array([plan.landmark_margin_mm(lm) for lm in plan.landmarks])
    max_safe = max_safe_depth_mm(plan, bracket_mm=grid_bracket(depth, clearance, margins))
    oov = _out_of_volume_depth_mm(volume, plan, lip, n_rings, n_angles)
    candidates = [
        (plan.planned_depth_mm, "planned_depth"),
        (max_safe, "margin"),
        (math.inf if oov is None else oov, "out_of_volume"),
    ]
    stop_depth, stop_reason = min(candidates, key=lambda c: c[0])  # ties: first listed wins
    stop_clearance = clearance_profile_mm(plan, plan.landmarks, np.array([stop_depth]))[0]
    if calibration.illustrative:
        warnings.append(
            LoadWarning(
                "calibration_illustrative",
                f"calibration {calibration.name!r} is illustrative (not measured on bone): "
                "forces show the pattern, not validated magnitudes",
            )
        )
    if profile.n_clipped:
        warnings.append(
            LoadWarning(
                "extrapolated",
                f"{profile.n_clipped} of {profile.n_samples} cut lip samples lie outside the "
                f"calibration's C' range {list(calibration.c_prime_range)}; clipped to it",
            )
        )
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
        out_of_volume_depth_mm=oov,
        stop_depth_mm=float(stop_depth),
        stop_reason=stop_reason,
        stop_clearance_mm=stop_clearance,
        warnings=tuple(warnings),
    )
