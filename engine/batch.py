"""Many trajectories of one plan over one CT: the answers of ``plan_path``, in one batch.

:func:`evaluate_batch` takes ``N`` candidate axes (entry and target points, LPS mm) that share
one plan's drill, landmarks, margins and calibration, and returns a :class:`BatchResult` whose
row ``n`` holds what :func:`ctdrill.engine.path.plan_path` computes for the plan with that
entry and target: the force profile (every :class:`~ctdrill.model.profile.Profile` array), the
clearance to every landmark at every depth, the max safe depth (capped or not, and the
binding landmark), the plan clearance, the out-of-volume depth, the stop depth and its reason.
A trajectory that ``plan_path`` would refuse (a slice gap crossed without
``interpolate_gaps``, padding touched, an entry outside the scan, a degenerate axis...) gets
that message in :attr:`BatchResult.refusal` and NaN in its rows: one bad candidate never
stops the batch. Problems of the volume or of the arguments themselves (a single slice,
values not HU, a bad depth step) concern every row and raise once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ctdrill.engine.path import (
    DEFAULT_DEPTH_STEP_MM,
    PathInputError,
)
from ctdrill.engine.rows import clearances_each, gap_checks, row_checks
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.clearance_batch import (
    STOP_REASONS,
    evaluate_clearances,
)
from ctdrill.imaging.plan.safety import margins_mm
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.lip import (
    DEFAULT_N_ANGLES,
    DEFAULT_N_RINGS,
    axis_basis,
    ring_radii_mm,
    sample_lip_rings,
)
from ctdrill.imaging.sampling.lip_batch import sample_lips
from ctdrill.imaging.sampling.path import (
    check_padding,
    check_volume,
)
from ctdrill.imaging.stack import wide_steps
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration, harmonic_freqs_hz
from ctdrill.model.profile_batch import build_profiles

__all__ = ["BatchResult", "evaluate_batch"]

#: Most trajectories one call accepts (memory: a row is ~50 kB at the default grid).
MAX_BATCH = 200_000
#: Rows sampled and integrated per pass (bounds the float32 ring-sample buffer: 256 rows of a
#: 16 mm path at the default lip are ~18 MB, reused).
CHUNK_ROWS = 256


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


def _points(value: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise PathInputError(f"{name}: expected an (N, 3) array of LPS mm, got shape {arr.shape}")
    return arr


def check_batch_arguments(
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
        raise PathInputError(f"depth_step_mm must be a positive number, got {depth_step_mm!r}")
    ring_radii_mm(2.0, n_rings)  # refuses a bad count with the sampler's own message
    ring_radii_mm(2.0, n_angles)
    check_volume(volume)
    return entries, targets


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
) -> BatchResult:
    """Evaluate ``N`` trajectories sharing ``plan``'s drill, landmarks and margins.

    Parameters
    ----------
    volume : the CT (LPS).
    plan : drill, landmarks, margins and feed (its own entry and target are not used).
    entries_lps, targets_lps : (N, 3) LPS mm; row ``n`` is one trajectory.
    calibration : force-law coefficients.
    depth_step_mm, n_rings, n_angles, interpolate_gaps : as for ``plan_path``.

    Returns
    -------
    BatchResult
        Row ``n`` equal (to 1e-9) to ``plan_path`` on ``plan`` with that entry and target, or
        the message ``plan_path`` refuses it with. The compiled kernels run when their cache
        is present (``python -m ctdrill.app.search.warmup``); otherwise the per-trajectory
        functions of ``plan_path`` run row by row, with the same answers.

    Raises
    ------
    PathInputError
        Bad arguments, a plan with a drill sequence (its forces need the earlier holes:
        evaluate ``plan.for_drill(k)``), or a volume no trajectory can use (a single slice,
        values not HU).
    """
    if plan.earlier_drills:
        sizes = ", ".join(f"{d.diameter_mm:g}" for d in plan.drills)
        raise PathInputError(
            f"plan {plan.name!r} drills a sequence ({sizes} mm): evaluate_batch computes one "
            "drill on a full lip, not a drill cutting around earlier holes; pass "
            "plan.for_drill(k) for drill k alone (plan_sequence computes a sequence's forces)"
        )
    entries, targets = check_batch_arguments(
        volume,
        entries_lps,
        targets_lps,
        depth_step_mm=depth_step_mm,
        n_rings=n_rings,
        n_angles=n_angles,
    )
    freqs = harmonic_freqs_hz(calibration, blades=plan.drill.blades, rpm=plan.drill.rpm)
    n = entries.shape[0]
    planned = np.array(
        [float(np.linalg.norm(t - e)) for e, t in zip(entries, targets, strict=True)]
    )
    refusal: list[str | None] = [None] * n
    landmarks, oov = row_checks(volume, plan, entries, targets, planned, refusal)
    gaps_possible = bool(np.any(wide_steps(volume.slice_positions_mm)))
    plan = replace(plan, landmarks=landmarks)
    if gaps_possible:
        gap_checks(volume, plan, entries, targets, planned, oov, refusal, interpolate_gaps)
    ok_rows = np.array([i for i in range(n) if refusal[i] is None], dtype=np.int64)
    n_dep = np.zeros(n, dtype=np.int64)
    steps = np.zeros(n)
    for i in ok_rows.tolist():
        n_dep[i] = max(2, math.ceil(planned[i] / depth_step_mm - 1e-9) + 1)
    d_max = int(n_dep.max()) if n else 0
    depth = np.full((n, d_max), np.nan)
    for m in np.unique(n_dep[ok_rows]).tolist():
        rows = ok_rows[n_dep[ok_rows] == m]
        steps[rows] = planned[rows] / (m - 1)  # np.linspace(0, planned, m), row by row
        depth[rows, :m] = np.arange(m, dtype=np.float64)[None, :] * steps[rows, None] + 0.0
        depth[rows, m - 1] = planned[rows]
    bases = np.zeros((n, 3, 3))
    for i in ok_rows.tolist():
        bases[i] = axis_basis(entries[i], targets[i])
    radii = ring_radii_mm(plan.drill.diameter_mm, n_rings)
    ring_w = np.full(n_rings, 1.0 / n_rings)
    area_w = radii / radii.sum()
    n_k = freqs.shape[0]
    s_t, hu_mean, s0, disc = (np.full((n, d_max), np.nan) for _ in range(4))
    sk = np.full((n, n_k, d_max), np.nan)
    n_clipped = np.zeros(n, dtype=np.int64)
    n_samples = np.zeros(n, dtype=np.int64)
    buf = np.empty((min(CHUNK_ROWS, max(n, 1)), d_max, n_rings, n_angles), dtype=np.float32)
    for start in range(0, ok_rows.size, CHUNK_ROWS):
        rows = ok_rows[start : start + CHUNK_ROWS]
        local = np.arange(rows.size)
        chunk = buf[: rows.size]
        if volume.valid is None:
            sample_lips(
                volume,
                entries[rows],
                targets[rows],
                bases[rows],
                depth[rows],
                n_dep[rows],
                plan.drill,
                n_rings=n_rings,
                n_angles=n_angles,
                out=chunk,
            )
        else:  # padding: the per-trajectory sampler and its padding check
            for j, i in enumerate(rows.tolist()):
                m = int(n_dep[i])
                lip = sample_lip_rings(
                    volume,
                    entries[i],
                    targets[i],
                    depth[i, :m],
                    plan.drill,
                    n_rings=n_rings,
                    n_angles=n_angles,
                )
                try:
                    check_padding(
                        volume,
                        entries[i],
                        targets[i],
                        plan.drill,
                        lip,
                        n_rings,
                        n_angles,
                        name=plan.name,
                    )
                except ImagingInputError as exc:
                    refusal[i] = str(exc)
                chunk[j, :m] = lip.hu
        prof = build_profiles(
            chunk,
            depth[rows],
            n_dep[rows],
            ring_w,
            calibration,
            blades=plan.drill.blades,
            rpm=plan.drill.rpm,
            alt_weights=area_w,
            rows=local,
        )
        s_t[rows], hu_mean[rows], s0[rows] = prof.s_t, prof.hu_mean, prof.s0_n
        sk[rows], disc[rows] = prof.sk_n, prof.hu_mean_alt
        n_clipped[rows], n_samples[rows] = prof.n_clipped, prof.n_samples
    ok_rows = np.array([i for i in ok_rows.tolist() if refusal[i] is None], dtype=np.int64)
    margins = margins_mm(plan)
    oov_or_inf = np.where(np.isnan(oov), np.inf, oov)
    clear = evaluate_clearances(
        plan.landmarks,
        margins,
        plan.drill.radius_mm,
        plan.drill.tip_length_mm,
        entries,
        targets,
        depth,
        n_dep,
        planned,
        oov_or_inf,
        ok_rows,
    )
    if clear is None:
        clear = clearances_each(plan, entries, targets, depth, n_dep, oov_or_inf, ok_rows)
    bad = np.array([r is not None for r in refusal], dtype=bool)
    n_l = len(plan.landmarks)
    for arr in (depth, s_t, hu_mean, s0, disc, sk):
        arr[bad] = np.nan
    n_dep[bad] = 0
    n_clipped[bad] = 0
    n_samples[bad] = 0
    plan_clear = np.full(n, np.nan)
    if n_l:
        for i in ok_rows.tolist():
            plan_clear[i] = float(clear.clearance_mm[i, n_dep[i] - 1].min())
    reason = np.full(n, "", dtype=object)
    for i in ok_rows.tolist():
        reason[i] = STOP_REASONS[int(clear.stop_reason[i])]
    oov[bad] = np.nan
    return BatchResult(
        entries_lps=entries.copy(),
        targets_lps=targets.copy(),
        planned_depth_mm=planned,
        n_depths=n_dep,
        depth_mm=depth,
        disc_hu=disc,
        hu_mean=hu_mean,
        s_t=s_t,
        s0_n=s0,
        sk_n=sk,
        freqs_hz=freqs,
        ke_per_mm_s=calibration.ke_per_mm_s,
        n_clipped=n_clipped,
        n_samples=n_samples,
        clearance_mm=clear.clearance_mm,
        margins_mm=margins,
        max_safe_depth_mm=clear.max_safe_depth_mm,
        max_safe_depth_capped=clear.capped,
        binding_landmark=clear.binding,
        plan_clearance_mm=plan_clear,
        out_of_volume_depth_mm=oov,
        stop_depth_mm=clear.stop_depth_mm,
        stop_reason=reason,
        stop_clearance_mm=clear.stop_clearance_mm,
        refusal=tuple(refusal),
    )
