"""The envelope rule of :mod:`ctdrill.imaging.sampling.envelope`, compiled: one ray at a time.

:func:`~ctdrill.imaging.sampling.envelope_march.envelope_rays` gives, for ``N`` rays, what
:func:`~ctdrill.imaging.sampling.envelope.envelope_walls` gives (the wall to the jaw's envelope,
unknown, open): each ray is marched and sampled (trilinear, the weights and summation order of
``scipy.ndimage.map_coordinates(order=1, mode="nearest")`` that
:meth:`~ctdrill.imaging.volume.CTVolume.sample` uses, the same hull test and true slice
positions for an irregular stack), the rule is read in one pass along it, and its exit crossing
is bisected on the CT, all in compiled code that releases the interpreter lock (a worker thread
measuring walls never starves the window). The NumPy path stays the reference: the two agree
to within :data:`~ctdrill.imaging.sampling.envelope.BISECT_TOL_MM` (tests hold them so).

The march reads only what the rule needs (on a regular grid): a ray steps over each block of
the CT whose trilinear field lies inside one class (:mod:`~ctdrill.imaging.sampling.hu_blocks`:
all soft, or all bone-range, cached with the volume) as one segment, and reads the other
samples (and the bisection's) at index coordinates extrapolated along the ray, the exact point's
own arithmetic taken wherever a sample lies within ``eps_hu`` of a threshold or near the CT's
faces. Once the exit's bisection bracket lies inside one trilinear cell, its midpoints are read
off the cell's cubic along the ray (:mod:`~ctdrill.imaging.sampling.cell_cubic`) under the
same guard. A ray that meets bone at or past the cap with the CT still there is decided
(capped, known, closed) and its march stops. Every decision of the rule is therefore the full
march's: the walls, unknown and open flags are bit for bit those of the march reading every
sample (``skip_blocks=False``; a Hypothesis test holds them so on adversarial fields).

Each call walks a span of rays up or down, claiming each (``taken``,
:func:`ctdrill.claims.start_claimed`), so two threads meet wherever the rays' costs put the middle.

The kernel covers volumes without padding; a padded volume and a process without the compiled
kernel take the NumPy path. Its samples are ``CTVolume.sample``'s bits (``trilinear`` with
map_coordinates' weights), so a sample exactly at a threshold is classed alike.
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.sampling.cell_cubic import cell_cubic
from ctdrill.imaging.sampling.hu_blocks import (
    AIR,
    BONE,
    GONE,
    MARGIN_VOX,
    MIXED,
    SOFT,
    TOOTH,
    block_run,
)
from ctdrill.imaging.sampling.trilinear import (
    VOLUME_SIG,
    at_index_inside,
    trilinear,
)
from ctdrill.jit import Kernel, helper


@helper
def _fast(
    vol: np.ndarray,
    top: np.ndarray,
    ci: float,
    cj: float,
    ck: float,
    air_hu: float,
    bone_hu: float,
    tooth_hu: float,
    eps_hu: float,
) -> float:  # pragma: no cover - compiled; tested against the full march
    """The trilinear sample at index coordinates extrapolated along a ray (not the exact
    point's own affine arithmetic: they differ by ~1e-12 voxel), or NaN when the exact sample
    must be read: near the hull's faces, or within ``eps_hu`` of a threshold (where that
    rounding could change the sample's class)."""
    if not (
        ci >= MARGIN_VOX
        and cj >= MARGIN_VOX
        and ck >= MARGIN_VOX
        and ci <= top[0] - MARGIN_VOX
        and cj <= top[1] - MARGIN_VOX
        and ck <= top[2] - MARGIN_VOX
    ):
        return np.nan
    h = at_index_inside(vol, ck, cj, ci)  # MARGIN_VOX inside: the clamps do nothing
    if abs(h - bone_hu) < eps_hu or abs(h - air_hu) < eps_hu or abs(h - tooth_hu) < eps_hu:
        return np.nan
    return h


def _envelope_kernel(
    vol: np.ndarray,
    inv_lin: np.ndarray,
    inv_off: np.ndarray,
    top: np.ndarray,
    k_nominal: np.ndarray,
    remap: bool,
    blocks: np.ndarray,
    origins: np.ndarray,
    dirs: np.ndarray,
    params: np.ndarray,
    ints: np.ndarray,
    wall: np.ndarray,
    unknown: np.ndarray,
    open_: np.ndarray,
    taken: np.ndarray,
    row_lo: int,
    row_hi: int,
    backward: bool,
) -> None:  # pragma: no cover - compiled by numba; tested against the NumPy path
    step, max_wall, reach, bone_hu, tooth_hu, air_hu, tol, eps_hu = (
        params[0],
        params[1],
        params[2],
        params[3],
        params[4],
        params[5],
        params[6],
        params[7],
    )
    n_steps, gap_steps, edge, k_cap = ints[0], ints[1], ints[2], ints[3]
    # skip uniform blocks only on a regular grid (index coordinates linear along the ray)
    accel = not remap and blocks.shape[0] > 0
    cls = np.empty(n_steps, dtype=np.int8)  # each sample's class, known for [0, filled)
    rend = np.empty(n_steps, dtype=np.int64)  # at a segment's start, its last sample
    coef = np.empty(4)  # the bisected cell's cubic along the ray
    k_reach = 0  # the first sample beyond the reach
    while k_reach < n_steps and not (k_reach * step > reach):
        k_reach += 1
    for idx in range(row_lo, row_hi):
        # rays claimed one by one (:func:`ctdrill.claims.start_claimed`): from the span's first
        # ray up, or from its last down; a ray another thread took ends this run
        n = row_hi - 1 - (idx - row_lo) if backward else idx
        if taken[n] != 0:
            break
        taken[n] = 1
        o0, o1, o2 = origins[n, 0], origins[n, 1], origins[n, 2]
        v0, v1, v2 = dirs[n, 0], dirs[n, 1], dirs[n, 2]
        # index coordinates along the ray (regular grids): c(t) = c0 + t e, a sample d apart
        ci0 = inv_lin[0, 0] * o0 + inv_lin[0, 1] * o1 + inv_lin[0, 2] * o2
        ci0 += inv_off[0]
        cj0 = inv_lin[1, 0] * o0 + inv_lin[1, 1] * o1 + inv_lin[1, 2] * o2
        cj0 += inv_off[1]
        ck0 = inv_lin[2, 0] * o0 + inv_lin[2, 1] * o1 + inv_lin[2, 2] * o2
        ck0 += inv_off[2]
        ei = inv_lin[0, 0] * v0 + inv_lin[0, 1] * v1 + inv_lin[0, 2] * v2
        ej = inv_lin[1, 0] * v0 + inv_lin[1, 1] * v1 + inv_lin[1, 2] * v2
        ek = inv_lin[2, 0] * v0 + inv_lin[2, 1] * v1 + inv_lin[2, 2] * v2
        # inverse index steps a sample (0: less than 1e-12 voxel, as good as none)
        di = 1.0 / (step * ei) if abs(step * ei) > 1e-12 else 0.0
        dj = 1.0 / (step * ej) if abs(step * ej) > 1e-12 else 0.0
        dk = 1.0 / (step * ek) if abs(step * ek) > 1e-12 else 0.0
        filled = 0  # samples classed so far: the march stops where the jaw ends
        mixed_to = -1  # samples up to this one lie in a block already found mixed
        last_bone = -1
        last_solid = -1
        first_gone = n_steps
        first_air = -1
        k_end = -1
        edge_at_end = False
        lb = -1
        k_far = -1
        prev_ok = False  # sample k-1: seen, not solid, not gone (a gap inside the CT)
        # bone met at or past the cap with the CT still there: capped, known, closed, whatever
        # follows (the full rule's far_first below), so the march stops there
        far_done = False
        k = 0  # the next sample the rule reads: the start of a segment (rend[k] its end)
        while k < n_steps:
            # class sample k (its segment), and for a bone-range segment the samples up to
            # `edge` past its end (a tooth there shortens its bone); nothing else looks ahead
            while filled <= k or (cls[k] == BONE and filled < min(n_steps, rend[k] + edge + 1)):
                t = filled * step
                if accel:
                    ci = ci0 + t * ei
                    cj = cj0 + t * ej
                    ck = ck0 + t * ek
                    if filled > mixed_to:
                        count, code = block_run(
                            vol, blocks, top, ci, cj, ck, di, dj, dk, air_hu, bone_hu, tooth_hu
                        )
                        if count > 0 and code != MIXED:  # a uniform block: one segment
                            hi = min(filled + count - 1, n_steps - 1)
                            for m in range(filled, hi + 1):
                                cls[m] = code
                            rend[filled] = hi
                            filled = hi + 1
                            continue
                        if count > 0:
                            mixed_to = filled + count - 1
                    h = _fast(vol, top, ci, cj, ck, air_hu, bone_hu, tooth_hu, eps_hu)
                    if np.isnan(h):
                        h = trilinear(
                            vol, inv_lin, inv_off, top, k_nominal, remap,
                            o0 + t * v0, o1 + t * v1, o2 + t * v2,
                        )  # fmt: skip
                else:
                    h = trilinear(
                        vol, inv_lin, inv_off, top, k_nominal, remap,
                        o0 + t * v0, o1 + t * v1, o2 + t * v2,
                    )  # fmt: skip
                if np.isnan(h):
                    cls[filled] = GONE
                elif h < air_hu:
                    cls[filled] = AIR
                elif h < bone_hu:
                    cls[filled] = SOFT
                elif h < tooth_hu:
                    cls[filled] = BONE
                else:
                    cls[filled] = TOOTH
                rend[filled] = filled
                filled += 1
            e = rend[k]
            c = cls[k]
            if c in (SOFT, BONE):
                # segment [k, e]: bone-range samples are bone except within `edge` samples of
                # a tooth (before it or after it), where they count as neither bone nor gap
                # end, as soft samples do
                b_lo = e + 1
                b_hi = e
                if c == BONE:
                    lt = -edge - 1
                    for j in range(max(0, k - edge), k):
                        if cls[j] == TOOTH:
                            lt = j
                    nt = n_steps + edge
                    for j in range(min(n_steps, e + edge + 1) - 1, e, -1):
                        if cls[j] == TOOTH:
                            nt = j
                    b_lo = max(k, lt + edge + 1)
                    b_hi = min(e, nt - edge - 1)
                    if b_lo > b_hi:
                        b_lo = e + 1
                        b_hi = e
                # soft samples [k, b_lo - 1], then bone [b_lo, b_hi], then soft [b_hi + 1, e]
                for part in range(2):
                    s_lo = k if part == 0 else b_hi + 1
                    s_hi = b_lo - 1 if part == 0 else e
                    if s_lo <= s_hi:
                        # nothing happens until the gap closes (after bone) or the reach
                        at = last_solid + gap_steps if last_bone >= 0 else k_reach
                        at = max(at, s_lo)
                        if at <= s_hi:
                            k_end = at
                            lb = last_bone
                            break
                        prev_ok = last_bone >= 0
                    if part == 0 and b_lo <= b_hi:
                        last_bone = b_hi
                        last_solid = b_hi
                        if k_far < 0 and b_hi >= k_cap:
                            k_far = max(b_lo, k_cap)
                            if first_gone == n_steps:
                                far_done = True
                                break
                        prev_ok = False
                if k_end >= 0 or far_done:
                    break
                k = e + 1
                continue
            # one sample outside the CT, of air or of tooth
            gone = c == GONE
            if gone and first_gone == n_steps:
                first_gone = k
            air = c == AIR
            if air and first_air < 0:
                first_air = k
            solid = c == TOOTH
            if solid:
                last_solid = k
            seen = last_bone >= 0
            end = air or (seen and not solid and k - last_solid >= gap_steps)
            if not seen and k >= k_reach:
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
            k += 1
        if far_done:
            wall[n] = max_wall
            unknown[n] = False
            open_[n] = False
            taken[n] = 2
            continue
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
        op = lb < 0 and first_gone > 0 and cls[ks] != AIR and (first_air < 0 or first_air > k_stop)
        if not unk and lb >= 0 and not capped:  # bisect the exit crossing
            a = lb * step
            b_t = min(lb + 1, n_steps - 1) * step
            # once the bracket lies inside one cell its midpoints are read off the cell's
            # cubic, where it is farther than eps_hu from the thresholds decided on (else,
            # and while the bracket spans cells, as the march reads them)
            a0 = a
            cubic = False
            while b_t - a > tol:
                if accel and not cubic:
                    a0 = a
                    cubic = cell_cubic(
                        vol, top, ci0 + a0 * ei, cj0 + a0 * ej, ck0 + a0 * ek,
                        ei, ej, ek, b_t - a0, coef,
                    )  # fmt: skip
                mid = 0.5 * (a + b_t)
                h = np.nan
                if cubic:
                    x = mid - a0
                    h = coef[0] + x * (coef[1] + x * (coef[2] + x * coef[3]))
                    if abs(h - bone_hu) < eps_hu or abs(h - tooth_hu) < eps_hu:
                        h = np.nan
                if accel and np.isnan(h):
                    h = _fast(
                        vol, top, ci0 + mid * ei, cj0 + mid * ej, ck0 + mid * ek,
                        air_hu, bone_hu, tooth_hu, eps_hu,
                    )  # fmt: skip
                if np.isnan(h):
                    h = trilinear(
                        vol, inv_lin, inv_off, top, k_nominal, remap,
                        o0 + mid * v0, o1 + mid * v1, o2 + mid * v2,
                    )  # fmt: skip
                if h >= bone_hu and h < tooth_hu:
                    a = mid
                else:
                    b_t = mid
            w = min(0.5 * (a + b_t), max_wall)
        wall[n] = w
        unknown[n] = unk
        open_[n] = op
        taken[n] = 2


_SIG = (
    "void(" + VOLUME_SIG + ", int8[:, :, ::1], "
    "float64[:, ::1], float64[:, ::1], float64[::1], int64[::1], float64[::1], boolean[::1], "
    "boolean[::1], uint8[::1], int64, int64, boolean)"
)
ENVELOPE_KERNEL = Kernel(
    _envelope_kernel, [_SIG.format(vol="int16"), _SIG.format(vol="float32")], readonly=(0, 4)
)
