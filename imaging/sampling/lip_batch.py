"""The cutting lip's HU for many trajectories at once (the batched form of ``lip.py``).

:func:`sample_lips` returns, for ``N`` trajectories sharing one drill, exactly the float32 ring
samples :func:`ctdrill.imaging.sampling.lip.sample_lip_rings` gives for each (the same ring
points, built with the same floating-point operations, the same trilinear weights (``1 - t``,
then 1 minus that) and summation order as ``scipy.ndimage.map_coordinates(order=1,
mode="nearest")`` that
:meth:`CTVolume.sample` uses, the same hull test and the same true slice positions for an
irregular stack). The compiled kernel covers volumes without padding; a padded volume (whose
sampler substitutes padding voxels) and a process without the compiled kernel use the
per-trajectory sampler itself.
"""

from __future__ import annotations

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.kernel_args import volume_args
from ctdrill.imaging.sampling.lip import ring_radii_mm, sample_lip_rings
from ctdrill.imaging.sampling.trilinear import at_index
from ctdrill.imaging.volume import CTVolume
from ctdrill.jit import Kernel, row_spans, run_spans

#: Tolerance of the hull test, voxels (CTVolume's own).
_EDGE_TOL_VOX = 1e-6


def _lip_kernel(
    vol: np.ndarray,
    inv_lin: np.ndarray,
    inv_off: np.ndarray,
    top: np.ndarray,
    k_nominal: np.ndarray,
    remap: bool,
    entries: np.ndarray,
    bases: np.ndarray,
    depth: np.ndarray,
    n_depth: np.ndarray,
    xi_off: np.ndarray,
    radii: np.ndarray,
    cos_t: np.ndarray,
    sin_t: np.ndarray,
    outside_hu: float,
    out: np.ndarray,
    outside: np.ndarray,
    row_lo: int,
    row_hi: int,
) -> None:  # pragma: no cover - compiled by numba; tested against sample_lip_rings
    n_s = k_nominal.shape[0]
    tol = 1e-6
    offsets = np.empty((radii.shape[0], cos_t.shape[0], 3))
    for n in range(row_lo, row_hi):
        ax0, ax1, ax2 = bases[n, 0, 0], bases[n, 0, 1], bases[n, 0, 2]
        for r in range(radii.shape[0]):  # the sampler's radii * (cos e1 + sin e2)
            for a in range(cos_t.shape[0]):
                for c in range(3):
                    unit = cos_t[a] * bases[n, 1, c] + sin_t[a] * bases[n, 2, c]
                    offsets[r, a, c] = radii[r] * unit
        for d in range(n_depth[n]):
            outside[n, d] = 0
            for r in range(radii.shape[0]):
                xi = depth[n, d] - xi_off[r]
                c0 = entries[n, 0] + xi * ax0
                c1 = entries[n, 1] + xi * ax1
                c2 = entries[n, 2] + xi * ax2
                for a in range(cos_t.shape[0]):
                    p0 = c0 + offsets[r, a, 0]
                    p1 = c1 + offsets[r, a, 1]
                    p2 = c2 + offsets[r, a, 2]
                    ck = inv_lin[2, 0] * p0 + inv_lin[2, 1] * p1 + inv_lin[2, 2] * p2
                    ck += inv_off[2]
                    cj = inv_lin[1, 0] * p0 + inv_lin[1, 1] * p1 + inv_lin[1, 2] * p2
                    cj += inv_off[1]
                    ci = inv_lin[0, 0] * p0 + inv_lin[0, 1] * p1 + inv_lin[0, 2] * p2
                    ci += inv_off[0]
                    if remap:  # np.interp on the true slice positions, linear beyond the ends
                        if ck < k_nominal[0]:
                            slope = 1.0 / (k_nominal[1] - k_nominal[0])
                            ck = 0.0 + (ck - k_nominal[0]) * slope
                        elif ck > k_nominal[n_s - 1]:
                            slope = 1.0 / (k_nominal[n_s - 1] - k_nominal[n_s - 2])
                            ck = (n_s - 1.0) + (ck - k_nominal[n_s - 1]) * slope
                        elif ck == k_nominal[n_s - 1]:
                            ck = n_s - 1.0
                        else:
                            j = np.searchsorted(k_nominal, ck, side="right") - 1
                            if k_nominal[j] == ck:
                                ck = float(j)
                            else:
                                slope = 1.0 / (k_nominal[j + 1] - k_nominal[j])
                                ck = slope * (ck - k_nominal[j]) + float(j)
                    if not (
                        ck >= -tol
                        and cj >= -tol
                        and ci >= -tol
                        and ck <= top[2] + tol
                        and cj <= top[1] + tol
                        and ci <= top[0] + tol
                    ):
                        out[n, d, r, a] = outside_hu
                        outside[n, d] += 1
                        continue
                    out[n, d, r, a] = at_index(vol, ck, cj, ci)  # mode="nearest"'s bits


_SIG = (
    "void({vol}[:, :, ::1], float64[:, ::1], float64[::1], float64[::1], float64[::1], boolean, "
    "float64[:, ::1], float64[:, :, ::1], float64[:, ::1], int64[::1], float64[::1], "
    "float64[::1], float64[::1], float64[::1], float64, float32[:, :, :, ::1], int64[:, ::1], "
    "int64, int64)"
)
LIP_KERNEL = Kernel(
    _lip_kernel, [_SIG.format(vol="int16"), _SIG.format(vol="float32")], readonly=(0, 4)
)


def sample_lips(
    volume: CTVolume,
    entries_lps: np.ndarray,
    targets_lps: np.ndarray,
    bases: np.ndarray,
    depth_mm: np.ndarray,
    n_depths: np.ndarray,
    drill: DrillSpec,
    *,
    n_rings: int,
    n_angles: int,
    rows: np.ndarray | None = None,
    out: np.ndarray | None = None,
    outside: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Ring samples of ``N`` trajectories, float32 (N, D, n_rings, n_angles), and the samples
    outside the volume (or on padding) per depth, int64 (N, D).

    Parameters
    ----------
    volume : the CT.
    entries_lps, targets_lps : (N, 3) LPS mm.
    bases : (N, 3, 3) :func:`~ctdrill.imaging.sampling.lip.axis_basis` of each trajectory.
    depth_mm : (N, D) tip depths (row ``n`` valid up to ``n_depths[n]``), mm.
    n_depths : (N,) depths per row.
    drill : the drill (diameter, tip length).
    n_rings, n_angles : lip discretisation.
    rows : which rows to sample (default all); the others are left as they are in ``out``.
    out, outside : optional buffers to fill, float32 (N, D, n_rings, n_angles), int64 (N, D).

    Returns
    -------
    tuple[np.ndarray, np.ndarray]
        ``hu`` and ``outside`` equal to :func:`sample_lip_rings`' of each row up to its
        ``n_depths`` (AIR_HU outside the voxel-centre hull): the compiled kernel where it is
        ready and the volume has no padding, the sampler itself row by row otherwise.
    """
    n, d_max = depth_mm.shape
    if out is None:
        out = np.empty((n, d_max, n_rings, n_angles), dtype=np.float32)
    if outside is None:
        outside = np.zeros((n, d_max), dtype=np.int64)
    todo = np.arange(n) if rows is None else np.asarray(rows, dtype=np.int64)
    if todo.size == 0:
        return out, outside
    if volume.valid is not None or not LIP_KERNEL.ready():  # the per-trajectory sampler
        for i in todo.tolist():
            m = int(n_depths[i])
            lip = sample_lip_rings(
                volume,
                entries_lps[i],
                targets_lps[i],
                depth_mm[i, :m],
                drill,
                n_rings=n_rings,
                n_angles=n_angles,
            )
            out[i, :m] = lip.hu
            outside[i, :m] = lip.outside
        return out, outside
    radius = float(drill.diameter_mm) / 2.0
    tip_len = float(drill.tip_length_mm)
    radii = ring_radii_mm(drill.diameter_mm, n_rings)
    theta = 2.0 * np.pi * np.arange(n_angles, dtype=np.float64) / n_angles
    xi_off = tip_len * radii / radius  # the sampler's xi = depth - tip_len * r / R
    args = volume_args(volume)
    ent = np.ascontiguousarray(entries_lps, dtype=np.float64)
    bas = np.ascontiguousarray(bases, dtype=np.float64)
    dep = np.ascontiguousarray(depth_mm, dtype=np.float64)
    nd = np.ascontiguousarray(n_depths, dtype=np.int64)
    rest = (xi_off, radii, np.cos(theta), np.sin(theta), float(AIR_HU), out, outside)
    run_spans(LIP_KERNEL, row_spans(todo), *args, ent, bas, dep, nd, *rest)
    return out, outside
