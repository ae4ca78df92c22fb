"""The envelope rule of :mod:`ctdrill.imaging.sampling.envelope`, compiled: one ray at a time.

:func:`envelope_rays` gives, for ``N`` rays, what
:func:`~ctdrill.imaging.sampling.envelope.envelope_walls` gives (the wall to the jaw's envelope,
unknown, open): each ray is marched and sampled (trilinear, the weights and summation order of
``scipy.ndimage.map_coordinates(order=1, mode="nearest")`` that
:meth:`~ctdrill.imaging.volume.CTVolume.sample` uses, the same hull test and true slice
positions for an irregular stack), the rule is read in one pass along it, and its exit crossing
is bisected on the CT, all in compiled code that releases the interpreter lock (a worker thread
measuring walls never starves the window). The NumPy path stays the reference: the two agree
to within :data:`~ctdrill.imaging.sampling.envelope.BISECT_TOL_MM` (tests hold them so).

The kernel covers volumes without padding; a padded volume and a process without the compiled
kernel take the NumPy path.
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.sampling.trilinear import VOLUME_SIG, fits, trilinear, volume_args
from ctdrill.imaging.teeth import TOOTH_HU
from ctdrill.imaging.volume import CTVolume
from ctdrill.jit import Kernel, row_spans, run_spans

#: Rays per thread span below which one thread does all (waking threads costs more).
_MIN_SPAN = 64


def _envelope_kernel(
    vol: np.ndarray,
    inv_lin: np.ndarray,
    inv_off: np.ndarray,
    top: np.ndarray,
    k_nominal: np.ndarray,
    remap: bool,
    origins: np.ndarray,
    dirs: np.ndarray,
    params: np.ndarray,
    ints: np.ndarray,
    wall: np.ndarray,
    unknown: np.ndarray,
    open_: np.ndarray,
    row_lo: int,
    row_hi: int,
) -> None:  # pragma: no cover - compiled by numba; tested against the NumPy path
    step, max_wall, reach, bone_hu, tooth_hu, air_hu, tol = (
        params[0],
        params[1],
        params[2],
        params[3],
        params[4],
        params[5],
        params[6],
    )
    n_steps, gap_steps, edge, k_cap = ints[0], ints[1], ints[2], ints[3]
    hu = np.empty(n_steps)
    tooth = np.zeros(n_steps, dtype=np.bool_)
    for n in range(row_lo, row_hi):
        o0, o1, o2 = origins[n, 0], origins[n, 1], origins[n, 2]
        v0, v1, v2 = dirs[n, 0], dirs[n, 1], dirs[n, 2]
        filled = 0  # samples read so far: the march stops where the jaw ends
        last_bone = -1
        last_solid = -1
        first_gone = n_steps
        first_air = -1
        k_end = -1
        edge_at_end = False
        lb = -1
        k_far = -1
        prev_ok = False  # sample k-1: seen, not solid, not gone (a gap inside the CT)
        for k in range(n_steps):
            while filled < min(n_steps, k + edge + 1):  # a tooth up to `edge` samples ahead
                t = filled * step
                h = trilinear(
                    vol,
                    inv_lin,
                    inv_off,
                    top,
                    k_nominal,
                    remap,
                    o0 + t * v0,
                    o1 + t * v1,
                    o2 + t * v2,
                )
                hu[filled] = h
                tooth[filled] = h >= tooth_hu
                filled += 1
            h = hu[k]
            bone = h >= bone_hu and h < tooth_hu
            if bone:  # not within `edge` samples of a tooth sample (its trilinear edge)
                for m in range(max(0, k - edge), min(n_steps, k + edge + 1)):
                    if tooth[m]:
                        bone = False
                        break
            gone = np.isnan(h)
            if gone and first_gone == n_steps:
                first_gone = k
            air = h < air_hu
            if air and first_air < 0:
                first_air = k
            solid = bone or tooth[k]
            if bone:
                last_bone = k
                if k >= k_cap and k_far < 0:
                    k_far = k
            if solid:
                last_solid = k
            seen = last_bone >= 0
            end = air or (seen and not solid and k - last_solid >= gap_steps)
            if not seen and k * step > reach:
                end = True
            edge_end = gone and prev_ok
            if edge_end:
                end = True
            if end:
                # nothing past the end changes the rule: the CT's edge, air and bone past
                # the cap count only before it
                k_end = k
                edge_at_end = edge_end
                lb = last_bone
                break
            prev_ok = seen and not solid and not gone
        has_end = k_end >= 0
        if not has_end:
            k_end = n_steps - 1
            lb = last_bone
        unk = first_gone < k_end or (first_gone == k_end and not edge_at_end)
        w = lb * step if lb >= 0 else 0.0
        capped = lb >= 0 and (lb * step >= max_wall or not has_end)
        far_first = k_far >= 0 and k_far < first_gone and (not has_end or k_end > k_far)
        if far_first:
            capped = True
            unk = False
        if capped:
            w = max_wall
        k_stop = min(k_end, first_gone - 1)
        ks = max(k_stop, 0)
        op = (
            lb < 0
            and first_gone > 0
            and not (hu[ks] < air_hu)
            and (first_air < 0 or first_air > k_stop)
        )
        if not unk and lb >= 0 and not capped:  # bisect the exit crossing
            a = lb * step
            b_t = min(lb + 1, n_steps - 1) * step
            while b_t - a > tol:
                mid = 0.5 * (a + b_t)
                h = trilinear(
                    vol,
                    inv_lin,
                    inv_off,
                    top,
                    k_nominal,
                    remap,
                    o0 + mid * v0,
                    o1 + mid * v1,
                    o2 + mid * v2,
                )
                if h >= bone_hu and h < tooth_hu:
                    a = mid
                else:
                    b_t = mid
            w = min(0.5 * (a + b_t), max_wall)
        wall[n] = w
        unknown[n] = unk
        open_[n] = op


_SIG = (
    "void(" + VOLUME_SIG + ", "
    "float64[:, ::1], float64[:, ::1], float64[::1], int64[::1], float64[::1], boolean[::1], "
    "boolean[::1], int64, int64)"
)
ENVELOPE_KERNEL = Kernel(
    _envelope_kernel, [_SIG.format(vol="int16"), _SIG.format(vol="float32")], readonly=(0, 4)
)


def kernel_fits(volume: CTVolume) -> bool:
    """The compiled kernel can read ``volume`` (no padding, int16 or float32 voxels) and is
    loaded from the cache."""
    return fits(volume) and ENVELOPE_KERNEL.ready()


def envelope_rays(
    volume: CTVolume,
    origins_lps: np.ndarray,
    dirs_lps: np.ndarray,
    *,
    step: float,
    n_steps: int,
    gap_steps: int,
    tooth_edge: int,
    max_wall_mm: float,
    reach_mm: float,
    air_hu: float,
    bisect_tol_mm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(wall, unknown, open)`` (N,) of each ray by the compiled kernel (only when
    :func:`kernel_fits`); the arguments are those of ``envelope_walls`` and its constants."""
    n = len(origins_lps)
    wall = np.zeros(n)
    unknown = np.zeros(n, dtype=np.bool_)
    open_ = np.zeros(n, dtype=np.bool_)
    if n == 0:
        return wall, unknown, open_
    k_cap = int(np.searchsorted(np.arange(n_steps) * step, max_wall_mm - 1e-12))
    params = np.array(
        [step, max_wall_mm, reach_mm, BONE_HU, TOOTH_HU, air_hu, bisect_tol_mm], dtype=np.float64
    )
    ints = np.array([n_steps, gap_steps, tooth_edge, k_cap], dtype=np.int64)
    spans = row_spans(np.arange(n)) if n >= 2 * _MIN_SPAN else [(0, n)]
    run_spans(
        ENVELOPE_KERNEL,
        spans,
        *volume_args(volume),
        np.ascontiguousarray(origins_lps, dtype=np.float64),
        np.ascontiguousarray(dirs_lps, dtype=np.float64),
        params,
        ints,
        wall,
        unknown,
        open_,
    )
    return wall, unknown, open_
