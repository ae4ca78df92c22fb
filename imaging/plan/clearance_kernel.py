"""The compiled clearance kernel of :mod:`ctdrill.imaging.plan.clearance_batch`: arrays only.

For ``N`` drill axes sharing one drill and one set of landmarks, the kernel fills the signed
clearance from the drill solid to every landmark at the depths asked for each row, the array
:func:`~ctdrill.imaging.plan.safety.clearance_profile_mm` gives for that axis. Asked to
(``stop_margin``, ``stop_tol``), a row stops at the first depth where some landmark's slack
``clearance - margin - tol`` is negative: the safe-depth search's passes read no depth after
that one. The rules that read it (the safe-depth search, the stop) are written once, in Python
(:func:`~ctdrill.imaging.plan.safety.search_safe_depths`, :mod:`ctdrill.engine.clearance`).

Every landmark is a union of segments (a canal's centreline with its radius, a point, a mask's
segments from :func:`~ctdrill.imaging.plan.voxels.voxel_union_segments`), and the clearance is
the minimum over them of the signed distance to the drill solid (a convex function along a
segment), minus the radius. The compiled kernel finds that minimum exactly, not by sampling:

- a segment is skipped when a lower bound is already above a value reached on the landmark
  (the previous depth's nearest point gives the first such value): the solid lies in
  ``{s <= x, rho <= R}`` (``s`` the depth along the axis, ``rho`` the distance from it, both
  bounded in closed form on the segment), so a segment is at least
  ``hypot(min s - x, min rho - R)`` away when both are positive, else
  ``max(min s - x, min rho - R)``; then the 1-Lipschitz bound from its two ends;
- the others are minimised on the segment's parameter by secant steps on the derivative
  (analytic: the unit vector from the nearest point of the solid), inside a bracket whose
  end tangents bound the minimum from below (convexity), until the value found is within
  1e-13 mm of that bound; the NumPy path's golden section stops at
  :data:`~ctdrill.imaging.plan.distance.SEGMENT_TOL_MM`. Where the drill is outside the
  landmark the distance is smooth at its minimum and both agree to ~1e-12 mm; inside a
  landmark (negative clearance) the signed distance has creases and the NumPy value is
  within SEGMENT_TOL_MM above this one.
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.jit import Kernel, helper


@helper
def _sd_grad(
    s: float, rho: float, x: float, radius: float, tip_len: float
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """distance.solid_distance_mm at one point, with its gradient ``(d/ds, d/drho)``: the
    unit vector from the nearest boundary point (negated inside)."""
    corner = x - tip_len
    vs_ray = max(s - corner, 0.0)
    vr_ray = rho - radius
    d_ray = math.sqrt(vs_ray * vs_ray + vr_ray * vr_ray)
    seg_len2 = tip_len * tip_len + radius * radius
    ds = s - corner
    dr = rho - radius
    t = (ds * tip_len - dr * radius) / seg_len2
    t = min(max(t, 0.0), 1.0)
    vs_cone = ds - t * tip_len
    vr_cone = dr + t * radius
    d_cone = math.sqrt(vs_cone * vs_cone + vr_cone * vr_cone)
    if d_ray <= d_cone:
        d, vs, vr = d_ray, vs_ray, vr_ray
    else:
        d, vs, vr = d_cone, vs_cone, vr_cone
    gs = vs / d if d > 0.0 else 0.0
    gr = vr / d if d > 0.0 else 0.0
    if s <= x and rho <= radius and rho * tip_len <= radius * (x - s):
        return -d, -gs, -gr
    return d, gs, gr


@helper
def _seg_eval(
    geo: np.ndarray, g: int, t: float, x: float, radius: float, tip_len: float
) -> tuple[float, float]:  # pragma: no cover - compiled
    """Signed distance at parameter ``t`` of segment ``g`` and its derivative in ``t``
    (``geo`` row: s_a, ds, perp_a (3), dperp (3), ...)."""
    s = geo[g, 0] + t * geo[g, 1]
    p0 = geo[g, 2] + t * geo[g, 5]
    p1 = geo[g, 3] + t * geo[g, 6]
    p2 = geo[g, 4] + t * geo[g, 7]
    rho = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    f, gs, gr = _sd_grad(s, rho, x, radius, tip_len)
    drho = (p0 * geo[g, 5] + p1 * geo[g, 6] + p2 * geo[g, 7]) / rho if rho > 0.0 else 0.0
    return f, gs * geo[g, 1] + gr * drho


@helper
def _seg_min(
    geo: np.ndarray, g: int, x: float, radius: float, tip_len: float, upper: float
) -> tuple[float, float]:  # pragma: no cover - compiled
    """(minimum, argmin) of the signed distance over segment ``g`` (a convex function of the
    parameter), or a value >= ``upper`` when it cannot go below ``upper``.

    The derivative's sign at the ends says whether the minimum is at an end; otherwise the
    tangents at the ends of the bracket bound the minimum from below (convexity), the
    bracket shrinks by secant steps on the derivative (Illinois), and the search stops when
    the best value is within 1e-13 mm of that lower bound, or the bound reaches ``upper``.
    """
    flo, dlo = _seg_eval(geo, g, 0.0, x, radius, tip_len)
    fhi, dhi = _seg_eval(geo, g, 1.0, x, radius, tip_len)
    best, best_t = (flo, 0.0) if flo <= fhi else (fhi, 1.0)
    if geo[g, 8] == 0.0 or dlo >= 0.0 or dhi <= 0.0:
        return best, best_t
    lo, hi = 0.0, 1.0
    wlo, whi = dlo, dhi  # Illinois-weighted derivatives for the secant step
    side = 0
    for _ in range(100):
        # tangents at lo and hi meet below the minimum (convex function)
        ti = (fhi - flo - dhi * hi + dlo * lo) / (dlo - dhi)
        lower = flo + dlo * (ti - lo)
        if lower >= upper or best - lower <= 1e-13 or hi - lo <= 1e-15:
            break
        t = (lo * whi - hi * wlo) / (whi - wlo)
        if not (lo < t < hi):
            t = 0.5 * (lo + hi)
        f, df = _seg_eval(geo, g, t, x, radius, tip_len)
        if f < best:
            best, best_t = f, t
        if df == 0.0:
            break
        if df < 0.0:
            lo, flo, dlo, wlo = t, f, df, df
            if side == -1:
                whi *= 0.5
            side = -1
        else:
            hi, fhi, dhi, whi = t, f, df, df
            if side == 1:
                wlo *= 0.5
            side = 1
    return best, best_t


@helper
def _landmark_min(
    geo: np.ndarray,
    order: np.ndarray,
    lo: int,
    hi: int,
    x: float,
    radius: float,
    tip_len: float,
    warm: np.ndarray,
    lm_i: int,
) -> float:  # pragma: no cover - compiled
    """Minimum signed distance over segments ``order[lo:hi]`` (sorted by their axis bound) at
    depth ``x``; ``warm[lm_i]`` holds the last minimiser (segment, parameter) and is updated."""
    if hi <= lo:
        return np.inf
    best = np.inf
    if warm[lm_i, 0] >= 0.0:
        best = _seg_eval(geo, int(warm[lm_i, 0]), warm[lm_i, 1], x, radius, tip_len)[0]
    for q in range(lo, hi):
        g = order[q]
        rho_lb = geo[g, 9]
        if rho_lb >= best:  # sorted by it: every later segment is at least as far
            break
        # the solid lies in {s <= x, rho <= R}: a point ahead of the tip plane and off the
        # cylinder is at least hypot(s - x, rho - R) away from it
        ahead = geo[g, 10] - x
        if ahead > 0.0 and rho_lb > 0.0:
            lower = math.sqrt(ahead * ahead + rho_lb * rho_lb) * (1.0 - 1e-12)
        else:
            lower = max(ahead, rho_lb)
        if lower >= best:
            continue
        val, t = _seg_min(geo, g, x, radius, tip_len, best)
        if val < best:
            best = val
            warm[lm_i, 0] = g
            warm[lm_i, 1] = t
    return best


@helper
def _clear_at(
    geo: np.ndarray,
    order: np.ndarray,
    lms: np.ndarray,
    x: float,
    radius: float,
    tip_len: float,
    radii_l: np.ndarray,
    warm: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Clearance to every landmark at depth ``x`` (``lms[lm_i]``: its segment rows in ``geo``)."""
    for lm_i in range(radii_l.shape[0]):
        out[lm_i] = (
            _landmark_min(geo, order, lms[lm_i, 0], lms[lm_i, 1], x, radius, tip_len, warm, lm_i)
            - radii_l[lm_i]
        )


def _rows_kernel(
    seg_a: np.ndarray,
    seg_b: np.ndarray,
    ptr: np.ndarray,
    radii_l: np.ndarray,
    entries: np.ndarray,
    dirs: np.ndarray,
    depth: np.ndarray,
    n_depth: np.ndarray,
    radius: float,
    tip_len: float,
    stop_margin: np.ndarray,
    stop_tol: float,
    clear_out: np.ndarray,
    row_lo: int,
    row_hi: int,
) -> None:  # pragma: no cover - compiled; tested against the NumPy path
    n_l = radii_l.shape[0]
    warm = np.empty((n_l, 2))
    tmp = np.empty(n_l)
    lms = np.empty((n_l, 2), dtype=np.int64)
    for n in range(row_lo, row_hi):
        # this row's segments in axis coordinates, each landmark's sorted by its axis bound
        total = 0
        for lm_i in range(n_l):
            total += ptr[n, lm_i, 1] - ptr[n, lm_i, 0]
        geo = np.empty((total, 11))
        order = np.empty(total, dtype=np.int64)
        u0, u1, u2 = dirs[n, 0], dirs[n, 1], dirs[n, 2]
        at = 0
        for lm_i in range(n_l):
            lms[lm_i, 0] = at
            for q in range(ptr[n, lm_i, 0], ptr[n, lm_i, 1]):
                r0 = seg_a[q, 0] - entries[n, 0]
                r1 = seg_a[q, 1] - entries[n, 1]
                r2 = seg_a[q, 2] - entries[n, 2]
                sa = r0 * u0 + r1 * u1 + r2 * u2
                b0 = seg_b[q, 0] - entries[n, 0]
                b1 = seg_b[q, 1] - entries[n, 1]
                b2 = seg_b[q, 2] - entries[n, 2]
                sb = b0 * u0 + b1 * u1 + b2 * u2
                pa0, pa1, pa2 = r0 - sa * u0, r1 - sa * u1, r2 - sa * u2
                pb0, pb1, pb2 = b0 - sb * u0, b1 - sb * u1, b2 - sb * u2
                dp0, dp1, dp2 = pb0 - pa0, pb1 - pa1, pb2 - pa2
                geo[at, 0] = sa
                geo[at, 1] = sb - sa
                geo[at, 2] = pa0
                geo[at, 3] = pa1
                geo[at, 4] = pa2
                geo[at, 5] = dp0
                geo[at, 6] = dp1
                geo[at, 7] = dp2
                e0, e1, e2 = b0 - r0, b1 - r1, b2 - r2
                geo[at, 8] = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                dd = dp0 * dp0 + dp1 * dp1 + dp2 * dp2
                t = 0.0
                if dd > 0.0:
                    t = min(max(-(pa0 * dp0 + pa1 * dp1 + pa2 * dp2) / dd, 0.0), 1.0)
                q0, q1, q2 = pa0 + t * dp0, pa1 + t * dp1, pa2 + t * dp2
                # a lower bound of min rho - R (a hair below it against rounding)
                geo[at, 9] = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2) - radius - 1e-12
                geo[at, 10] = min(sa, sb) - 1e-12
                at += 1
            lms[lm_i, 1] = at
            if lms[lm_i, 1] > lms[lm_i, 0]:
                # a stable sort: ties in the same order in compiled code and in Python
                order[lms[lm_i, 0] : lms[lm_i, 1]] = lms[lm_i, 0] + np.argsort(
                    geo[lms[lm_i, 0] : lms[lm_i, 1], 9], kind="mergesort"
                )
        warm[:, 0] = -1.0
        for d in range(n_depth[n]):
            _clear_at(geo, order, lms, depth[n, d], radius, tip_len, radii_l, warm, tmp)
            broken = False
            for lm_i in range(n_l):
                clear_out[n, d, lm_i] = tmp[lm_i]
                # the safe-depth rule's slack, with its operations: (c - margin) - tol
                if (tmp[lm_i] - stop_margin[lm_i]) - stop_tol < 0.0:
                    broken = True
            if broken:  # the depths after it are not read (stop_margin -inf: never)
                break


_SIG = (
    "void(float64[:, ::1], float64[:, ::1], int64[:, :, ::1], float64[::1], "
    "float64[:, ::1], float64[:, ::1], float64[:, ::1], int64[::1], float64, float64, "
    "float64[::1], float64, float64[:, :, ::1], int64, int64)"
)
#: interpretable: one trajectory's rows run as this Python function give the compiled bits
#: (IEEE +, -, *, /, sqrt and comparisons in the same order, a stable sort), ~20 ms a plan.
CLEARANCE_KERNEL = Kernel(_rows_kernel, [_SIG], interpretable=True)
