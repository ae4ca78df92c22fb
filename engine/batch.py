"""Many trajectories of one plan over one CT, in one batch: the engine's path.

:func:`evaluate_rows` is the one engine. It takes ``N`` candidate axes (entry and target
points, LPS mm) that share one plan's drill, landmarks, margins and calibration, and runs the
path's stages on every row at once: the checks before sampling (:mod:`ctdrill.engine.checks`:
coordinates, depth, masks, the volume edge, slice gaps), the depth grid
(:mod:`ctdrill.engine.grid`), the lip and its force profile (:mod:`ctdrill.engine.lips`:
padding), then clearance, safe depth and stop (:mod:`ctdrill.engine.clearance`). The single
trajectory (:func:`ctdrill.engine.path.plan_path`) is its one-row case; :func:`evaluate_batch`
returns its :class:`BatchResult`.

A trajectory the engine refuses (a slice gap crossed without ``interpolate_gaps``, padding
touched, an entry outside the scan, a degenerate axis...) gets that message in
:attr:`BatchResult.refusal` and NaN in its rows: one bad candidate never stops the batch.
Problems of the volume or of the arguments themselves (a single slice, values not HU, a bad
depth step) concern every row and raise once.

A new per-trajectory quantity is one more stage here, filling one more ``(N, ...)`` array of
:class:`BatchResult` (and of :class:`~ctdrill.engine.path.PathResult` for its row); a new
warning is one check in :mod:`ctdrill.engine.path_warnings`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ctdrill.engine import refusals
from ctdrill.engine.checks import check_arguments, check_rows
from ctdrill.engine.clearance import evaluate_stops
from ctdrill.engine.grid import DEFAULT_DEPTH_STEP_MM, depth_grids
from ctdrill.engine.lips import no_lips, sample_rows
from ctdrill.imaging.plan.clearance_batch import ClearanceField
from ctdrill.imaging.plan.safety import margins_mm
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.annulus import Hole
from ctdrill.imaging.sampling.lip import DEFAULT_N_ANGLES, DEFAULT_N_RINGS, LipSamples
from ctdrill.imaging.sampling.path import SliceGap
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration, harmonic_freqs_hz

__all__ = ["BatchResult", "RowsRun", "evaluate_batch", "evaluate_rows"]


@dataclass(frozen=True, eq=False)
class BatchResult:
    """What :func:`~ctdrill.engine.path.plan_path` computes, for ``N`` trajectories at once.

    Rows of different planned depths have different depth counts: per-depth arrays have
    ``D = max(n_depths)`` columns and NaN past a row's own ``n_depths[n]``. Refused rows
    (:attr:`refusal` not None) hold NaN everywhere (``n_depths`` 0, ``binding_landmark`` -1,
    ``stop_reason`` ``""``).

    Attributes
    ----------
    entries_lps, targets_lps : (N, 3) the trajectories, LPS mm.
    planned_depth_mm : (N,) ``|target - entry|``, mm.
    n_depths : (N,) depths in each row's uniform grid (``depth_grid_mm``).
    depth_mm : (N, D) tip depths from the entry, mm.
    disc_hu : (N, D) area-weighted mean HU over the lip's disc (ring ``i`` weighs
        ``(2 i + 1) / n_rings**2``, the area of its annulus): the bone the drill body meets.
    hu_mean, s_t, s0_n : (N, D) the profile's lip-mean HU, cut fraction and DC force (N).
    sk_n : (N, K, D) the profile's harmonic amplitudes, N.
    freqs_hz : (K,) harmonic frequencies (shared: one drill), Hz.
    ke_per_mm_s : the calibration's feed sensitivity, per (mm/s).
    n_clipped, n_samples : (N,) the profile's extrapolated samples and samples in all.
    clearance_mm : (N, D, L) signed clearance to each landmark at each depth, mm.
    margins_mm : (L,) margin per landmark (shared), mm.
    max_safe_depth_mm : (N,) deepest depth keeping every margin, mm.
    max_safe_depth_capped : (N,) bool, the search reached its limit safely.
    binding_landmark : (N,) index of the binding landmark (-1: none, as ``None``).
    plan_clearance_mm : (N,) smallest clearance over the planned path, mm (NaN: no landmark).
    out_of_volume_depth_mm : (N,) where the lip's data end before the planned depth, mm
        (NaN: the lip stays inside).
    stop_depth_mm : (N,) min(planned, max safe, out of volume), mm.
    stop_reason : (N,) ``planned_depth`` | ``margin`` | ``out_of_volume`` (``""`` refused).
    stop_clearance_mm : (N, L) clearance at the stop depth, mm.
    refusal : (N,) None, or the message ``plan_path`` refuses the trajectory with.
    """

    entries_lps: np.ndarray
    targets_lps: np.ndarray
    planned_depth_mm: np.ndarray
    n_depths: np.ndarray
    depth_mm: np.ndarray
    disc_hu: np.ndarray
    hu_mean: np.ndarray
    s_t: np.ndarray
    s0_n: np.ndarray
    sk_n: np.ndarray
    freqs_hz: np.ndarray
    ke_per_mm_s: float
    n_clipped: np.ndarray
    n_samples: np.ndarray
    clearance_mm: np.ndarray
    margins_mm: np.ndarray
    max_safe_depth_mm: np.ndarray
    max_safe_depth_capped: np.ndarray
    binding_landmark: np.ndarray
    plan_clearance_mm: np.ndarray
    out_of_volume_depth_mm: np.ndarray
    stop_depth_mm: np.ndarray
    stop_reason: np.ndarray
    stop_clearance_mm: np.ndarray
    refusal: tuple[str | None, ...]

    def __post_init__(self) -> None:
        for value in vars(self).values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
        object.__setattr__(self, "refusal", tuple(self.refusal))

    @property
    def size(self) -> int:
        """``N``, the number of trajectories."""
        return int(self.entries_lps.shape[0])

    @property
    def ok(self) -> np.ndarray:
        """(N,) bool: the trajectory was evaluated (not refused)."""
        return np.array([r is None for r in self.refusal], dtype=bool)

    def plan_for(self, plan: Plan, index: int) -> Plan:
        """``plan`` with row ``index``'s entry and target (what ``plan_path`` would drill)."""
        return replace(plan, entry_lps=self.entries_lps[index], target_lps=self.targets_lps[index])


@dataclass(frozen=True, eq=False)
class RowsRun:
    """What :func:`evaluate_rows` computed, with what the single path reads of its row.

    Attributes
    ----------
    batch : the per-row arrays.
    plan : the plan with its landmarks bound to the CT grid.
    errors : per row, None or the refusal (the exception the single path raises).
    gaps : per row, the slice gaps the lip reaches into (interpolated on request).
    lips : the ring samples of the rows asked to keep them.
    """

    batch: BatchResult
    plan: Plan
    errors: list[Exception | None]
    gaps: list[tuple[SliceGap, ...]]
    lips: dict[int, LipSamples]


def evaluate_rows(
    volume: CTVolume,
    plan: Plan,
    entries_lps: np.ndarray,
    targets_lps: np.ndarray,
    calibration: Calibration,
    *,
    depth_step_mm: float = DEFAULT_DEPTH_STEP_MM,
    n_rings: int = DEFAULT_N_RINGS,
    n_angles: int = DEFAULT_N_ANGLES,
    interpolate_gaps: bool = False,
    holes: tuple[Hole, ...] = (),
    keep_lips: bool = False,
    profiles: bool = True,
) -> RowsRun:
    """The engine on ``N`` rows (see the module docstring); ``holes`` are the earlier drills'
    of a sequence (shared along every axis: the profile counts the lip outside them),
    ``keep_lips`` keeps each row's ring samples; ``profiles=False`` computes the stops only
    (:func:`evaluate_batch`)."""
    entries, targets = check_arguments(
        volume,
        entries_lps,
        targets_lps,
        depth_step_mm=depth_step_mm,
        n_rings=n_rings,
        n_angles=n_angles,
    )
    freqs = harmonic_freqs_hz(calibration, blades=plan.drill.blades, rpm=plan.drill.rpm)
    checks = check_rows(volume, plan, entries, targets, interpolate_gaps=interpolate_gaps)
    if len(checks.landmarks) != len(plan.landmarks) or any(
        a is not b for a, b in zip(checks.landmarks, plan.landmarks, strict=True)
    ):
        plan = replace(plan, landmarks=checks.landmarks)
    errors = checks.errors
    planned, oov = checks.planned_mm, checks.out_of_volume_mm
    ok_rows = checks.ok_rows()
    n_dep, depth = depth_grids(planned, depth_step_mm, ok_rows)
    # the lip is sampled for its profile, and on a padded volume for the padding rule too
    sample = sample_rows if profiles or keep_lips or volume.valid is not None else no_lips
    lips = sample(
        volume,
        plan,
        calibration,
        entries,
        targets,
        depth,
        n_dep,
        ok_rows,
        errors,
        n_rings=n_rings,
        n_angles=n_angles,
        n_harmonics=freqs.shape[0],
        holes=tuple(holes),
        keep=keep_lips,
    )
    ok_rows = np.array([i for i in ok_rows.tolist() if errors[i] is None], dtype=np.int64)
    margins = margins_mm(plan)
    field = ClearanceField.prepare(
        plan.landmarks, plan.drill.radius_mm, plan.drill.tip_length_mm, entries, targets, ok_rows
    )
    stops = evaluate_stops(field, margins, depth, n_dep, planned, oov, ok_rows, full_grid=profiles)
    bad = np.array([e is not None for e in errors], dtype=bool)
    arrays = (depth, lips.s_t, lips.hu_mean, lips.s0_n, lips.disc_hu, lips.sk_n, stops.clearance_mm)
    for arr in arrays:
        if arr.flags.writeable:  # not computed (stops only): already NaN everywhere
            arr[bad] = np.nan
    for arr in (n_dep, lips.n_clipped, lips.n_samples):
        arr[bad] = 0
    oov[bad] = np.nan
    batch = BatchResult(
        entries_lps=entries.copy(),
        targets_lps=targets.copy(),
        planned_depth_mm=planned,
        n_depths=n_dep,
        depth_mm=depth,
        disc_hu=lips.disc_hu,
        hu_mean=lips.hu_mean,
        s_t=lips.s_t,
        s0_n=lips.s0_n,
        sk_n=lips.sk_n,
        freqs_hz=freqs,
        ke_per_mm_s=calibration.ke_per_mm_s,
        n_clipped=lips.n_clipped,
        n_samples=lips.n_samples,
        clearance_mm=stops.clearance_mm,
        margins_mm=margins,
        max_safe_depth_mm=np.where(bad, np.nan, stops.max_safe_depth_mm),
        max_safe_depth_capped=stops.capped & ~bad,
        binding_landmark=np.where(bad, -1, stops.binding),
        plan_clearance_mm=np.where(bad, np.nan, stops.plan_clearance_mm),
        out_of_volume_depth_mm=oov,
        stop_depth_mm=np.where(bad, np.nan, stops.stop_depth_mm),
        stop_reason=np.where(bad, "", stops.stop_reason).astype(object),
        stop_clearance_mm=np.where(bad[:, None], np.nan, stops.stop_clearance_mm),
        refusal=tuple(None if e is None else str(e) for e in errors),
    )
    return RowsRun(batch, plan, errors, checks.gaps, lips.lips)


def evaluate_batch(
    volume: CTVolume,
    plan: Plan,
    entries_lps: np.ndarray,
    targets_lps: np.ndarray,
    calibration: Calibration,
    *,
    depth_step_mm: float = DEFAULT_DEPTH_STEP_MM,
    n_rings: int = DEFAULT_N_RINGS,
    n_angles: int = DEFAULT_N_ANGLES,
    interpolate_gaps: bool = False,
    profiles: bool = True,
) -> BatchResult:
    """Evaluate ``N`` trajectories sharing ``plan``'s drill, landmarks and margins.

    Parameters
    ----------
    volume : the CT (LPS).
    plan : drill, landmarks, margins and feed (its own entry and target are not used).
    entries_lps, targets_lps : (N, 3) LPS mm; row ``n`` is one trajectory.
    calibration : force-law coefficients.
    depth_step_mm, n_rings, n_angles, interpolate_gaps : as for ``plan_path``.
    profiles : False: the stops only (what a search that reads the max safe depth, the
        binding landmark, the clearance at the planned depth and the stop needs): no lip
        profile (``disc_hu``, ``hu_mean``, ``s_t``, ``s0_n``, ``sk_n`` NaN, the sample counts
        0) and the clearance on the grid only where the stops need it (``clearance_mm`` NaN
        elsewhere; the planned depth's is kept). Every stop, max safe depth, binding landmark
        and refusal is the one of the full evaluation.

    Returns
    -------
    BatchResult
        Row ``n`` is ``plan_path`` on ``plan`` with that entry and target (the same engine),
        or the message ``plan_path`` refuses it with. The compiled kernels run when their
        cache is present (``python -m ctdrill.app.search.warmup``); otherwise the NumPy
        path, with the same answers.

    Raises
    ------
    PathInputError
        Bad arguments, a plan with a drill sequence (its forces need the earlier holes:
        evaluate ``plan.for_drill(k)``), or a volume no trajectory can use (a single slice,
        values not HU).
    """
    if plan.earlier_drills:
        raise refusals.drill_sequence(plan)
    return evaluate_rows(
        volume,
        plan,
        entries_lps,
        targets_lps,
        calibration,
        depth_step_mm=depth_step_mm,
        n_rings=n_rings,
        n_angles=n_angles,
        interpolate_gaps=interpolate_gaps,
        profiles=profiles,
    ).batch
