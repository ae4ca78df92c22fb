"""The numpy peer of ``evaluate_batch``: the same work vectorised over all trajectories.

Written for ``bench_search`` as a fair plain-NumPy batch: every trajectory's lip points at
once through ``scipy.ndimage.map_coordinates(order=1, mode="nearest")`` (the volume's own
sampler, regular unpadded stacks), the force law on all samples at once (NumPy exp/log10),
and the clearance with the same closed-form pieces as the kernel (the signed distance to the
drill solid and its derivative along a segment; the segment's axis bounds), vectorised over
(trajectory, depth, segment) instead of pruned one by one: end values and derivatives of
every segment at every depth, then secant steps on the derivative for the pairs whose minimum
lies inside, and the max safe depth by the same 65-point passes (bisection, one depth per
trajectory per step, vectorised over trajectories).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from ctdrill.hu import AIR_HU
from ctdrill.imaging.plan.distance import SEGMENT_TOL_MM
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.safety import SAFE_DEPTH_TOL_MM, SEARCH_BEYOND_PLAN_MM
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration, Harmonic, PowerLaw

_LN10 = math.log(10.0)
#: Trajectories per vectorised pass: (32 x 241 depths x 83 segments) pairs of temporaries,
#: tens of MB; all rows at once would need several GB.
CHUNK = 32


def lip_hu(
    volume: CTVolume, entries: np.ndarray, targets: np.ndarray, plan: Plan, depth: np.ndarray
) -> np.ndarray:
    """(N, D, 6, 12) float32 ring samples (uniform depth grids of one length)."""
    n_r, n_a = 6, 12
    d = targets - entries
    axis = d / np.linalg.norm(d, axis=1)[:, None]
    helper = np.zeros_like(axis)
    helper[np.arange(len(axis)), np.argmin(np.abs(axis), axis=1)] = 1.0
    e1 = helper - np.sum(helper * axis, axis=1)[:, None] * axis
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(axis, e1)
    radius = plan.drill.radius_mm
    radii = (np.arange(n_r) + 0.5) * radius / n_r
    theta = 2.0 * np.pi * np.arange(n_a) / n_a
    xi = depth[:, :, None] - plan.drill.tip_length_mm * radii / radius  # (N, D, R)
    unit = (
        np.cos(theta)[None, :, None] * e1[:, None, :]
        + np.sin(theta)[None, :, None] * e2[:, None, :]
    )  # (N, A, 3)
    pts = (
        entries[:, None, None, None, :]
        + xi[..., None, None] * axis[:, None, None, None, :]
        + radii[None, None, :, None, None] * unit[:, None, None, :, :]
    )
    inv = np.linalg.inv(volume.affine_lps)
    idx = pts.reshape(-1, 3) @ inv[:3, :3].T + inv[:3, 3]
    top = np.array(volume.dims, dtype=np.float64) - 1.0
    inside = np.all((idx >= -1e-6) & (idx <= top + 1e-6), axis=1)
    out = np.empty(idx.shape[0])
    ndimage.map_coordinates(
        volume.hu, idx[:, ::-1].T, output=out, order=1, mode="nearest", prefilter=False
    )
    out[~inside] = AIR_HU
    return out.reshape(pts.shape[:-1]).astype(np.float32)


def profiles(hu: np.ndarray, cal: Calibration) -> dict[str, np.ndarray]:
    """S0, Sk, s_t and the lip-mean HU of every row (N, D) from (N, D, R, A) samples."""
    h = hu.astype(np.float64)
    w = cal.gate_width_hu
    g = np.clip((h - (cal.gate_hu - 0.5 * w)) / w, 0.0, 1.0)
    lo, hi = cal.c_prime_range
    log_cp = np.log10(np.clip(h - AIR_HU, lo, hi))
    weight = 1.0 / (hu.shape[2] * hu.shape[3])
    out = {"s_t": g.sum(axis=(2, 3)) * weight, "hu": h.sum(axis=(2, 3)) * weight}
    laws: list[tuple[str, PowerLaw | Harmonic]] = [("s0", cal.a0)]
    laws += [(f"s{h.order}", h) for h in cal.harmonics]
    for name, law in laws:
        out[name] = (np.exp(_LN10 * (law.b0 + law.n * log_cp)) * g).sum(axis=(2, 3)) * weight
    return out


def _sd_grad(
    s: np.ndarray, rho: np.ndarray, x: np.ndarray, radius: float, tip: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed distance to the drill solid and its gradient (d/ds, d/drho), vectorised."""
    corner = x - tip
    vs_r = np.maximum(s - corner, 0.0)
    vr_r = rho - radius
    d_r = np.hypot(vs_r, vr_r)
    ds = s - corner
    t = np.clip((ds * tip - vr_r * radius) / (tip * tip + radius * radius), 0.0, 1.0)
    vs_c = ds - t * tip
    vr_c = vr_r + t * radius
    d_c = np.hypot(vs_c, vr_c)
    ray = d_r <= d_c
    d = np.where(ray, d_r, d_c)
    safe = np.where(d > 0.0, d, 1.0)
    gs = np.where(ray, vs_r, vs_c) / safe
    gr = np.where(ray, vr_r, vr_c) / safe
    inside = (s <= x) & (rho <= radius) & (rho * tip <= radius * (x - s))
    sign = np.where(inside, -1.0, 1.0)
    return sign * d, sign * gs, sign * gr


class Segments:
    """One canal's segments in each trajectory's axis frame: (N, S) arrays."""

    def __init__(self, entries: np.ndarray, targets: np.ndarray, canal: CanalLandmark) -> None:
        a, b = canal.segments_lps()
        d = targets - entries
        u = d / np.linalg.norm(d, axis=1)[:, None]
        ra = a[None, :, :] - entries[:, None, :]
        rb = b[None, :, :] - entries[:, None, :]
        self.sa = np.einsum("nsc,nc->ns", ra, u)
        sb = np.einsum("nsc,nc->ns", rb, u)
        self.pa = ra - self.sa[..., None] * u[:, None, :]
        self.dp = (rb - sb[..., None] * u[:, None, :]) - self.pa
        self.ds = sb - self.sa
        self.radius_mm = float(canal.radius_mm)

    def clearance(self, x: np.ndarray, radius: float, tip: float, steps: int = 40) -> np.ndarray:
        """(N, D) clearance at depths ``x`` (N, D): minimum over segments minus the radius."""
        n_rows, n_dep = x.shape
        n_seg = self.sa.shape[1]
        # every (row, depth, segment) pair, flattened
        rows = np.repeat(np.arange(n_rows), n_dep * n_seg)
        segs = np.tile(np.arange(n_seg), n_rows * n_dep)
        xs = np.repeat(x.reshape(-1), n_seg)
        sa, ds = self.sa[rows, segs], self.ds[rows, segs]
        pa, dp = self.pa[rows, segs], self.dp[rows, segs]
        f0, d0 = _pair_value(sa, ds, pa, dp, np.zeros(xs.size), xs, radius, tip)
        f1, d1 = _pair_value(sa, ds, pa, dp, np.ones(xs.size), xs, radius, tip)
        best = np.minimum(f0, f1)
        inner = np.flatnonzero((d0 < 0.0) & (d1 > 0.0))
        if inner.size:
            lo, hi = np.zeros(inner.size), np.ones(inner.size)
            dlo, dhi = d0[inner], d1[inner]
            args = (sa[inner], ds[inner], pa[inner], dp[inner])
            val = best[inner]
            for _ in range(steps):  # secant on the derivative, bisection as a guard
                t = (lo * dhi - hi * dlo) / (dhi - dlo)
                t = np.where((t > lo) & (t < hi), t, 0.5 * (lo + hi))
                f, df = _pair_value(*args, t, xs[inner], radius, tip)
                val = np.minimum(val, f)
                neg = df < 0.0
                lo, dlo = np.where(neg, t, lo), np.where(neg, df, dlo)
                hi, dhi = np.where(neg, hi, t), np.where(neg, dhi, df)
            best[inner] = val
        out: np.ndarray = best.reshape(n_rows, n_dep, n_seg).min(axis=2) - self.radius_mm
        return out


def _pair_value(
    sa: np.ndarray,
    ds: np.ndarray,
    pa: np.ndarray,
    dp: np.ndarray,
    t: np.ndarray,
    x: np.ndarray,
    radius: float,
    tip: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance and its derivative in ``t`` for (P,) pairs (segment, depth)."""
    p = pa + t[:, None] * dp
    rho = np.sqrt(np.einsum("pc,pc->p", p, p))
    f, gs, gr = _sd_grad(sa + t * ds, rho, x, radius, tip)
    drho = np.einsum("pc,pc->p", p, dp) / np.where(rho > 0.0, rho, 1.0)
    return f, gs * ds + gr * drho


def safe_depths(
    seg: Segments,
    planned: np.ndarray,
    margin: float,
    radius: float,
    tip: float,
    depth: np.ndarray,
    clearance: np.ndarray,
) -> np.ndarray:
    """Max safe depth per trajectory by the 65-point passes (bisection), all rows at once,
    starting from the grid step where the margin is first broken (as ``safe_depth`` does)."""
    n = planned.size
    lo = np.zeros(n)
    hi = planned + SEARCH_BEYOND_PLAN_MM
    broken = clearance < margin
    first = np.argmax(broken, axis=1)
    bracket = broken.any(axis=1) & (first > 0)
    rows = np.flatnonzero(bracket)
    lo[rows] = depth[rows, first[rows] - 1]
    hi[rows] = depth[rows, first[rows]]

    def bad(x: np.ndarray) -> np.ndarray:
        out: np.ndarray = seg.clearance(x[:, None], radius, tip)[:, 0] - margin - SEGMENT_TOL_MM < 0
        return out

    capped = ~bad(hi)
    at_entry = bad(lo)
    active = ~capped & ~at_entry
    while active.any():
        step = (hi - lo) / 64.0
        good = np.zeros(n, dtype=np.int64)
        worse = np.where(active, 64, 1)
        while np.any(worse - good > 1):
            open_ = worse - good > 1
            mid = (good + worse) // 2
            viol = bad(np.where(open_, mid * step + lo, lo))
            worse = np.where(open_ & viol, mid, worse)
            good = np.where(open_ & ~viol, mid, good)
        new_lo = good * step + lo
        new_hi = np.where(worse == 64, hi, worse * step + lo)
        lo = np.where(active, new_lo, lo)
        hi = np.where(active, new_hi, hi)
        active &= hi - lo > SAFE_DEPTH_TOL_MM
    return np.where(capped, hi, np.where(at_entry, 0.0, lo))


def evaluate(
    volume: CTVolume,
    plan: Plan,
    entries: np.ndarray,
    targets: np.ndarray,
    cal: Calibration,
    depth: np.ndarray,
) -> dict[str, np.ndarray]:
    """Profiles, clearance per depth and max safe depth of every trajectory (one canal)."""
    canal = plan.landmarks[0]
    assert isinstance(canal, CanalLandmark)
    radius, tip = plan.drill.radius_mm, plan.drill.tip_length_mm
    margin = plan.landmark_margin_mm(canal)
    parts: list[dict[str, np.ndarray]] = []
    for c in range(0, entries.shape[0], CHUNK):  # chunks of rows bound the temporaries
        rows = slice(c, c + CHUNK)
        out = profiles(lip_hu(volume, entries[rows], targets[rows], plan, depth[rows]), cal)
        seg = Segments(entries[rows], targets[rows], canal)
        out["clearance"] = seg.clearance(depth[rows], radius, tip)
        planned = np.linalg.norm(targets[rows] - entries[rows], axis=1)
        args = (depth[rows], out["clearance"])
        out["max_safe"] = safe_depths(seg, planned, margin, radius, tip, *args)
        parts.append(out)
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
