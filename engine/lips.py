"""The lip and the force profile of every row: ring samples, padding, the lip integral.

:func:`~ctdrill.imaging.sampling.lip_batch.sample_lips` and
:func:`~ctdrill.model.profile_batch.build_profiles` compute the arrays: their compiled kernels
where they are ready, the sampler and :func:`~ctdrill.model.profile.build_profile` row by row
otherwise (a padded volume, whose sampler substitutes padding voxels, or no kernels' cache).
A drill cutting around earlier holes (rings per depth) takes the sampler and
``build_profile`` row by row. The padding rule reads each row's counts of samples outside.
Rows are sampled in chunks of :data:`CHUNK_ROWS`, one float32 buffer reused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.annulus import Hole, holes_on_grid
from ctdrill.imaging.sampling.lip import LipSamples, axis_basis, ring_radii_mm, sample_lip_rings
from ctdrill.imaging.sampling.lip_batch import sample_lips
from ctdrill.imaging.sampling.path import check_padding
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration
from ctdrill.model.profile import build_profile
from ctdrill.model.profile_batch import build_profiles

#: Rows sampled and integrated per pass (bounds the float32 ring-sample buffer: 256 rows of a
#: 16 mm path at the default lip are ~18 MB, reused).
CHUNK_ROWS = 256


@dataclass(frozen=True, eq=False)
class LipRun:
    """Per-row profile arrays (NaN past a row's depths and in rows not computed).

    Attributes
    ----------
    hu_mean, s_t, s0_n, disc_hu : (N, D).
    sk_n : (N, K, D).
    n_clipped, n_samples : (N,) int64.
    lips : the ring samples of the rows asked to keep them (row -> LipSamples).
    """

    hu_mean: np.ndarray
    s_t: np.ndarray
    s0_n: np.ndarray
    disc_hu: np.ndarray
    sk_n: np.ndarray
    n_clipped: np.ndarray
    n_samples: np.ndarray
    lips: dict[int, LipSamples]


def sample_rows(
    volume: CTVolume,
    plan: Plan,
    calibration: Calibration,
    entries: np.ndarray,
    targets: np.ndarray,
    depth: np.ndarray,
    n_dep: np.ndarray,
    rows: np.ndarray,
    errors: list[Exception | None],
    *,
    n_rings: int,
    n_angles: int,
    n_harmonics: int,
    holes: tuple[Hole, ...] = (),
    keep: bool = False,
) -> LipRun:
    """Sample every row's lip and integrate its profile; a row whose lip touches padding (at
    or ahead of the entry) gets its refusal in ``errors``. ``keep`` keeps each row's
    :class:`LipSamples` (with the HU on the axis at the tip)."""
    n, d_max = depth.shape
    drill = plan.drill
    radii = ring_radii_mm(drill.diameter_mm, n_rings)
    ring_w = np.full(n_rings, 1.0 / n_rings)
    area_w = radii / radii.sum()
    s_t, hu_mean, s0, disc = (np.full((n, d_max), np.nan) for _ in range(4))
    sk = np.full((n, n_harmonics, d_max), np.nan)
    n_clipped = np.zeros(n, dtype=np.int64)
    n_samples = np.zeros(n, dtype=np.int64)
    lips: dict[int, LipSamples] = {}
    if holes:  # rings per depth: the sampler and build_profile, row by row
        for i in rows.tolist():
            m = int(n_dep[i])
            on_grid = holes_on_grid(holes, depth[i, :m])
            lip = sample_lip_rings(
                volume,
                entries[i],
                targets[i],
                depth[i, :m],
                drill,
                n_rings=n_rings,
                n_angles=n_angles,
                holes=on_grid,
            )
            _padding(
                volume, plan, entries[i], targets[i], lip, n_rings, n_angles, on_grid, errors, i
            )
            prof = build_profile(
                lip.hu,
                lip.ring_weights,
                depth[i, :m],
                calibration,
                blades=drill.blades,
                rpm=drill.rpm,
            )
            s_t[i, :m], hu_mean[i, :m], s0[i, :m] = prof.s_t, prof.hu_mean, prof.s0_n
            sk[i, :, :m] = prof.sk_n
            n_clipped[i], n_samples[i] = prof.n_clipped, prof.n_samples
            if keep:
                lips[i] = lip
        return LipRun(hu_mean, s_t, s0, disc, sk, n_clipped, n_samples, lips)
    buf = np.empty((min(CHUNK_ROWS, max(n, 1)), d_max, n_rings, n_angles), dtype=np.float32)
    outs = np.zeros((buf.shape[0], d_max), dtype=np.int64)
    for start in range(0, rows.size, CHUNK_ROWS):
        chunk_rows = rows[start : start + CHUNK_ROWS]
        chunk, out_chunk = buf[: chunk_rows.size], outs[: chunk_rows.size]
        bases = np.stack([axis_basis(entries[i], targets[i]) for i in chunk_rows.tolist()])
        sample_lips(
            volume,
            entries[chunk_rows],
            targets[chunk_rows],
            bases,
            depth[chunk_rows],
            n_dep[chunk_rows],
            drill,
            n_rings=n_rings,
            n_angles=n_angles,
            out=chunk,
            outside=out_chunk,
        )
        prof_b = build_profiles(
            chunk,
            depth[chunk_rows],
            n_dep[chunk_rows],
            ring_w,
            calibration,
            blades=drill.blades,
            rpm=drill.rpm,
            alt_weights=area_w,
            rows=np.arange(chunk_rows.size),
        )
        s_t[chunk_rows], hu_mean[chunk_rows], s0[chunk_rows] = (
            prof_b.s_t,
            prof_b.hu_mean,
            prof_b.s0_n,
        )
        sk[chunk_rows], disc[chunk_rows] = prof_b.sk_n, prof_b.hu_mean_alt
        n_clipped[chunk_rows], n_samples[chunk_rows] = prof_b.n_clipped, prof_b.n_samples
        if volume.valid is None and not keep:
            continue
        for j, i in enumerate(chunk_rows.tolist()):
            m = int(n_dep[i])
            tips = entries[i] + depth[i, :m, None] * bases[j, 0]
            lip = LipSamples(
                depth_mm=depth[i, :m].copy(),
                radii_mm=radii,
                ring_weights=ring_w,
                hu=chunk[j, :m].copy(),
                outside=out_chunk[j, :m].copy(),
                axis_hu=volume.sample(tips, order=1, outside_hu=AIR_HU),
            )
            _padding(volume, plan, entries[i], targets[i], lip, n_rings, n_angles, (), errors, i)
            if keep:
                lips[i] = lip
    return LipRun(hu_mean, s_t, s0, disc, sk, n_clipped, n_samples, lips)


def no_lips(
    volume: CTVolume,
    plan: Plan,
    calibration: Calibration,
    entries: np.ndarray,
    targets: np.ndarray,
    depth: np.ndarray,
    n_dep: np.ndarray,
    rows: np.ndarray,
    errors: list[Exception | None],
    *,
    n_rings: int,
    n_angles: int,
    n_harmonics: int,
    holes: tuple[Hole, ...] = (),
    keep: bool = False,
) -> LipRun:
    """:func:`sample_rows`' arrays, not computed (NaN, read-only views of one value; no
    sample): for an evaluation of the stops only on a volume without padding (no padding rule
    to apply)."""
    n, d_max = depth.shape
    nan = np.broadcast_to(np.float64(np.nan), (n, d_max))
    zero = np.zeros(n, dtype=np.int64)
    sk = np.broadcast_to(np.float64(np.nan), (n, n_harmonics, d_max))
    return LipRun(nan, nan, nan, nan, sk, zero, zero.copy(), {})


def _padding(
    volume: CTVolume,
    plan: Plan,
    entry: np.ndarray,
    target: np.ndarray,
    lip: LipSamples,
    n_rings: int,
    n_angles: int,
    holes: tuple[Hole, ...],
    errors: list[Exception | None],
    row: int,
) -> None:
    """The padding rule on one row's lip (nothing to check on a volume without padding)."""
    if volume.valid is None:
        return
    try:
        check_padding(
            volume, entry, target, plan.drill, lip, n_rings, n_angles, name=plan.name, holes=holes
        )
    except ImagingInputError as exc:
        errors[row] = exc
