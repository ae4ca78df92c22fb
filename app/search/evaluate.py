"""Many trajectories of one plan over one CT: the answers of ``plan_path``, in one batch.

:func:`evaluate_batch` takes ``N`` candidate axes (entry and target points, LPS mm) that share
one plan's drill, landmarks, margins and calibration, and returns a :class:`BatchResult` whose
row ``n`` holds what :func:`ctdrill.app.pipeline.plan_path` computes for the plan with that
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

from ctdrill.app.pipeline import DEFAULT_DEPTH_STEP_MM, PathInputError, PathResult, plan_path
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.safety import margins_mm
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.lip import DEFAULT_N_ANGLES, DEFAULT_N_RINGS, ring_radii_mm
from ctdrill.imaging.sampling.path import check_volume
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration, harmonic_freqs_hz
from ctdrill.model.errors import ModelInputError

__all__ = ["BatchResult", "evaluate_batch"]

#: Most trajectories one call accepts (memory: a row is ~50 kB at the default grid).
MAX_BATCH = 200_000


@dataclass(frozen=True, eq=False)
class BatchResult:
    """What :func:`~ctdrill.app.pipeline.plan_path` computes, for ``N`` trajectories at once.

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
        the message ``plan_path`` refuses it with.

    Raises
    ------
    PathInputError
        Bad arguments, or a volume no trajectory can use (a single slice, values not HU).
    """
    entries, targets = check_batch_arguments(
        volume,
        entries_lps,
        targets_lps,
        depth_step_mm=depth_step_mm,
        n_rings=n_rings,
        n_angles=n_angles,
    )
    return _evaluate_each(
        volume,
        plan,
        entries,
        targets,
        calibration,
        depth_step_mm=depth_step_mm,
        n_rings=n_rings,
        n_angles=n_angles,
        interpolate_gaps=interpolate_gaps,
    )


def _evaluate_each(
    volume: CTVolume,
    plan: Plan,
    entries: np.ndarray,
    targets: np.ndarray,
    calibration: Calibration,
    *,
    depth_step_mm: float,
    n_rings: int,
    n_angles: int,
    interpolate_gaps: bool,
) -> BatchResult:
    """One ``plan_path`` per row (the reference the batched kernels are tested against)."""
    n = entries.shape[0]
    results: list[PathResult | None] = []
    refusal: list[str | None] = []
    for e, t in zip(entries, targets, strict=True):
        try:
            res = plan_path(
                volume,
                replace(plan, entry_lps=e, target_lps=t),
                calibration,
                depth_step_mm=depth_step_mm,
                n_rings=n_rings,
                n_angles=n_angles,
                interpolate_gaps=interpolate_gaps,
            )
        except (ImagingInputError, ModelInputError) as exc:
            results.append(None)
            refusal.append(str(exc))
        else:
            results.append(res)
            refusal.append(None)
    n_l = len(plan.landmarks)
    freqs = harmonic_freqs_hz(calibration, blades=plan.drill.blades, rpm=plan.drill.rpm)
    n_k = freqs.shape[0]
    n_dep = np.array([0 if r is None else r.depth_mm.shape[0] for r in results], dtype=np.int64)
    d_max = int(n_dep.max()) if n else 0
    radii = ring_radii_mm(plan.drill.diameter_mm, n_rings)
    area_w = radii / radii.sum()

    def per_depth() -> np.ndarray:
        return np.full((n, d_max), np.nan)

    depth, disc, hu_mean, s_t, s0 = (per_depth() for _ in range(5))
    sk = np.full((n, n_k, d_max), np.nan)
    clearance = np.full((n, d_max, n_l), np.nan)
    stop_clear = np.full((n, n_l), np.nan)
    scalars = {
        k: np.full(n, np.nan)
        for k in ("max_safe", "plan_clear", "oov", "stop", "n_clipped", "n_samples")
    }
    capped = np.zeros(n, dtype=bool)
    binding = np.full(n, -1, dtype=np.int64)
    reason = np.full(n, "", dtype=object)
    for i, r in enumerate(results):
        if r is None:
            continue
        m = r.depth_mm.shape[0]
        depth[i, :m] = r.depth_mm
        disc[i, :m] = r.lip.hu.mean(axis=2, dtype=np.float64) @ area_w
        hu_mean[i, :m] = r.profile.hu_mean
        s_t[i, :m] = r.profile.s_t
        s0[i, :m] = r.profile.s0_n
        sk[i, :, :m] = r.profile.sk_n
        clearance[i, :m] = r.clearance_mm
        stop_clear[i] = r.stop_clearance_mm
        scalars["max_safe"][i] = r.max_safe_depth_mm
        scalars["plan_clear"][i] = np.nan if r.plan_clearance_mm is None else r.plan_clearance_mm
        scalars["oov"][i] = np.nan if r.out_of_volume_depth_mm is None else r.out_of_volume_depth_mm
        scalars["stop"][i] = r.stop_depth_mm
        scalars["n_clipped"][i] = r.profile.n_clipped
        scalars["n_samples"][i] = r.profile.n_samples
        capped[i] = r.max_safe_depth_capped
        binding[i] = -1 if r.binding_landmark is None else r.binding_landmark
        reason[i] = r.stop_reason
    return BatchResult(
        entries_lps=entries.copy(),
        targets_lps=targets.copy(),
        planned_depth_mm=np.linalg.norm(targets - entries, axis=1),
        n_depths=n_dep,
        depth_mm=depth,
        disc_hu=disc,
        hu_mean=hu_mean,
        s_t=s_t,
        s0_n=s0,
        sk_n=sk,
        freqs_hz=freqs,
        ke_per_mm_s=calibration.ke_per_mm_s,
        n_clipped=np.nan_to_num(scalars["n_clipped"], nan=0.0).astype(np.int64),
        n_samples=np.nan_to_num(scalars["n_samples"], nan=0.0).astype(np.int64),
        clearance_mm=clearance,
        margins_mm=margins_mm(plan),
        max_safe_depth_mm=scalars["max_safe"],
        max_safe_depth_capped=capped,
        binding_landmark=binding,
        plan_clearance_mm=scalars["plan_clear"],
        out_of_volume_depth_mm=scalars["oov"],
        stop_depth_mm=scalars["stop"],
        stop_reason=reason,
        stop_clearance_mm=stop_clear,
        refusal=tuple(refusal),
    )
