"""The compiled twin of :func:`~ctdrill.imaging.plan.distance.segments_distance_mm`: arrays only.

The signed distance from a union of segments to a convex solid of revolution (the swept drill,
an implant body: any :class:`~ctdrill.imaging.plan.revolution.Meridian`) placed at each of
``D`` depths. The kernel runs the NumPy path's algorithm point by point, so both give the same
minimum to the same accuracy:

- the meridian's signed distance at a point (:meth:`Meridian.signed_distance_mm`, piece by
  piece: ray, segment, arc);
- a segment is skipped when its lower bound (the 1-Lipschitz bound from its two ends and its
  midpoint) is not below the least value already reached (an end, a midpoint or a minimised
  segment: every such value is a real distance, so no skipped segment could lower it);
- the others are minimised by golden section on the segment parameter until the bracket times
  the segment's length is below the tolerance (the NumPy path uses the longest length of the
  segments it minimises together: a few more steps, the same bound).

Each value the kernel returns is a distance it evaluated, so it is never below the true
minimum, and it is within ``tol_mm`` above it. :func:`segments_numpy` is its NumPy twin (the
same operations in the same order, each segment's own step count, the minima and their ties
taken in the kernel's order): the same bits, so a clearance does not depend on whether its
process loaded numba. :func:`~ctdrill.imaging.plan.distance.golden_segments_distance_mm` (all
segments at once) is the independent reference both are tested against, within ``tol_mm``.
The meridian is passed as rows ``(kind, a0, a1, b0, b1)`` (:func:`meridian_rows`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ctdrill.imaging.plan.revolution import ARC, RAY, SEGMENT, Meridian
from ctdrill.jit import Kernel, helper

_KIND = {RAY: 0.0, SEGMENT: 1.0, ARC: 2.0}


@functools.lru_cache(maxsize=64)
def meridian_rows(meridian: Meridian) -> np.ndarray:
    """(P, 5) the meridian's pieces as the kernel reads them: ``(kind, a0, a1, b0, b1)`` with
    kind 0 ray, 1 segment, 2 arc (:class:`~ctdrill.imaging.plan.revolution.Piece`); read-only,
    shared by every call with an equal meridian."""
    rows = np.array(
        [[_KIND[p.kind], p.a[0], p.a[1], p.b[0], p.b[1]] for p in meridian.pieces],
        dtype=np.float64,
    ).reshape(-1, 5)
    rows.flags.writeable = False
    return rows


@helper
def _meridian_sd(pieces: np.ndarray, u: float, rho: float) -> float:  # pragma: no cover
    """Meridian.signed_distance_mm at one point ``(u, rho)`` (``rho >= 0``)."""
    dist = np.inf
    below = False
    for k in range(pieces.shape[0]):
        kind = pieces[k, 0]
        if kind == 0.0:
            u_end, r = pieces[k, 1], pieces[k, 2]
            d = math.hypot(max(u - u_end, 0.0), rho - r)
            if u <= u_end and rho <= r:
                below = True
        elif kind == 1.0:
            u0, r0, u1, r1 = pieces[k, 1], pieces[k, 2], pieces[k, 3], pieces[k, 4]
            du, dr = u1 - u0, r1 - r0
            pu, pr = u - u0, rho - r0
            len2 = du * du + dr * dr
            t = 0.0
            if len2 > 0.0:
                t = min(max((pu * du + pr * dr) / len2, 0.0), 1.0)
            d = math.hypot(pu - t * du, pr - t * dr)
            if du > 0.0 and u >= u0 and u <= u1 and rho * du <= r0 * du + dr * pu:
                below = True
        else:
            uc, a, c0, s0 = pieces[k, 1], pieces[k, 2], pieces[k, 3], pieces[k, 4]
            rel = u - uc
            radial = math.hypot(rel, rho)
            if rel * s0 - rho * c0 >= 0.0:
                d = abs(radial - a)
            else:
                d = min(math.hypot(rel - a * c0, rho - a * s0), math.hypot(rel - a, rho))
            if rel >= a * c0 and radial <= a:
                below = True
        dist = min(dist, d)
    return -dist if below else dist


@helper
def _point_sd(
    pieces: np.ndarray,
    entry: np.ndarray,
    axis: np.ndarray,
    p0: float,
    p1: float,
    p2: float,
    x: float,
) -> float:  # pragma: no cover - compiled
    """Signed distance from the point ``(p0, p1, p2)`` (LPS mm) to the solid placed at ``x``
    (axial coordinate and offset as ``distance.axial_coordinates``)."""
    r0, r1, r2 = p0 - entry[0], p1 - entry[1], p2 - entry[2]
    s = r0 * axis[0] + r1 * axis[1] + r2 * axis[2]
    q0, q1, q2 = r0 - s * axis[0], r1 - s * axis[1], r2 - s * axis[2]
    return _meridian_sd(pieces, s - x, math.sqrt(q0 * q0 + q1 * q1 + q2 * q2))


@helper
def _golden(
    pieces: np.ndarray,
    entry: np.ndarray,
    axis: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    g: int,
    x: float,
    tol: float,
    inv_phi: float,
    start: float,
) -> float:  # pragma: no cover - compiled
    """Golden-section minimum of the (convex) signed distance along segment ``g`` at depth
    ``x``, ``start`` the least of its end values."""
    a0, a1, a2 = a[g, 0], a[g, 1], a[g, 2]
    d0, d1, d2 = b[g, 0] - a0, b[g, 1] - a1, b[g, 2] - a2
    length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if length <= tol:
        return start
    lo, hi = 0.0, 1.0
    c = hi - inv_phi * (hi - lo)
    d = lo + inv_phi * (hi - lo)
    fc = _point_sd(pieces, entry, axis, a0 + c * d0, a1 + c * d1, a2 + c * d2, x)
    fd = _point_sd(pieces, entry, axis, a0 + d * d0, a1 + d * d1, a2 + d * d2, x)
    steps = math.ceil(math.log(tol / length) / math.log(inv_phi))
    for _ in range(steps):
        if fc <= fd:  # convexity: a minimiser lies in [lo, d]
            hi = d
            d, fd = c, fc
            c = hi - inv_phi * (hi - lo)
            fc = _point_sd(pieces, entry, axis, a0 + c * d0, a1 + c * d1, a2 + c * d2, x)
        else:  # ... else in [c, hi]
            lo = c
            c, fc = d, fd
            d = lo + inv_phi * (hi - lo)
            fd = _point_sd(pieces, entry, axis, a0 + d * d0, a1 + d * d1, a2 + d * d2, x)
    return min(start, fc, fd)


def _segments_kernel(
    pieces: np.ndarray,
    entry: np.ndarray,
    axis: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    depth: np.ndarray,
    tol: float,
    inv_phi: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the NumPy path
    n_s = a.shape[0]
    va = np.empty(n_s)
    vb = np.empty(n_s)
    lower = np.empty(n_s)
    for j in range(depth.shape[0]):
        x = depth[j]
        best = np.inf
        for g in range(n_s):
            fa = _point_sd(pieces, entry, axis, a[g, 0], a[g, 1], a[g, 2], x)
            fb = _point_sd(pieces, entry, axis, b[g, 0], b[g, 1], b[g, 2], x)
            m0 = 0.5 * (a[g, 0] + b[g, 0])
            m1 = 0.5 * (a[g, 1] + b[g, 1])
            m2 = 0.5 * (a[g, 2] + b[g, 2])
            fm = _point_sd(pieces, entry, axis, m0, m1, m2, x)
            e0, e1, e2 = b[g, 0] - a[g, 0], b[g, 1] - a[g, 1], b[g, 2] - a[g, 2]
            half = 0.5 * math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            va[g] = fa
            vb[g] = fb
            # 1-Lipschitz: on a half of length L/2 between values u and v the function stays
            # above (u + v - L/2) / 2
            lower[g] = 0.5 * (min(fa, fb) + fm - half)
            best = min(best, fa, fb, fm)
        for g in range(n_s):
            if lower[g] < best:
                val = _golden(pieces, entry, axis, a, b, g, x, tol, inv_phi, min(va[g], vb[g]))
                best = min(best, val)
        out[j] = best


_SIG = (
    "void(float64[:, ::1], float64[::1], float64[::1], float64[:, ::1], float64[:, ::1], "
    "float64[::1], float64, float64, float64[::1])"
)
SEGMENTS_KERNEL = Kernel(_segments_kernel, [_SIG], readonly=(0, 1, 2, 3, 4, 5))


def _lesser(a: np.ndarray, b: np.ndarray | float) -> np.ndarray:
    """Python's (and the kernel's) ``min(a, b)`` elementwise: ``b`` only where ``b < a``."""
    return np.where(b < a, b, a)


def _greater(a: np.ndarray, b: np.ndarray | float) -> np.ndarray:
    """Python's (and the kernel's) ``max(a, b)`` elementwise: ``b`` only where ``b > a``."""
    return np.where(b > a, b, a)


def _meridian_sd_numpy(pieces: np.ndarray, u: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """:func:`_meridian_sd` elementwise: the same operations in the same order."""
    dist = np.full(u.shape, np.inf)
    below = np.zeros(u.shape, dtype=bool)
    for k in range(pieces.shape[0]):
        kind = pieces[k, 0]
        if kind == 0.0:
            u_end, r = pieces[k, 1], pieces[k, 2]
            d = np.hypot(_greater(u - u_end, 0.0), rho - r)
            below |= (u <= u_end) & (rho <= r)
        elif kind == 1.0:
            u0, r0, u1, r1 = pieces[k, 1], pieces[k, 2], pieces[k, 3], pieces[k, 4]
            du, dr = u1 - u0, r1 - r0
            pu, pr = u - u0, rho - r0
            len2 = du * du + dr * dr
            t = np.zeros(u.shape)
            if len2 > 0.0:
                t = _lesser(_greater((pu * du + pr * dr) / len2, 0.0), 1.0)
            d = np.hypot(pu - t * du, pr - t * dr)
            if du > 0.0:
                below |= (u >= u0) & (u <= u1) & (rho * du <= r0 * du + dr * pu)
        else:
            uc, a, c0, s0 = pieces[k, 1], pieces[k, 2], pieces[k, 3], pieces[k, 4]
            rel = u - uc
            radial = np.hypot(rel, rho)
            outer = np.abs(radial - a)
            ends = _lesser(np.hypot(rel - a * c0, rho - a * s0), np.hypot(rel - a, rho))
            d = np.where(rel * s0 - rho * c0 >= 0.0, outer, ends)
            below |= (rel >= a * c0) & (radial <= a)
        dist = _lesser(dist, d)
    return np.where(below, -dist, dist)


def _point_sd_numpy(
    pieces: np.ndarray,
    entry: np.ndarray,
    axis: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    p2: np.ndarray,
    x: np.ndarray,
) -> np.ndarray:
    """:func:`_point_sd` elementwise."""
    r0, r1, r2 = p0 - entry[0], p1 - entry[1], p2 - entry[2]
    s = r0 * axis[0] + r1 * axis[1] + r2 * axis[2]
    q0, q1, q2 = r0 - s * axis[0], r1 - s * axis[1], r2 - s * axis[2]
    return _meridian_sd_numpy(pieces, s - x, np.sqrt(q0 * q0 + q1 * q1 + q2 * q2))


def segments_numpy(
    pieces: np.ndarray,
    entry: np.ndarray,
    axis: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    depth: np.ndarray,
    tol: float,
    inv_phi: float,
    out: np.ndarray,
) -> None:
    """:func:`_segments_kernel` with NumPy, the kernel's bits: every distance is evaluated with
    the kernel's operations in its order, each segment takes its own number of golden-section
    steps, and the minima, the pruning and their ties are taken in the kernel's order. The
    (depth, segment) pairs are vectorised; only the running minimum walks the segments."""
    n_s, n_d = a.shape[0], depth.shape[0]
    if n_s == 0:
        out[:] = np.inf
        return
    x = depth[:, None]  # (D, 1) against (1, S)
    sd = functools.partial(_point_sd_numpy, pieces, entry, axis)
    fa = sd(a[None, :, 0], a[None, :, 1], a[None, :, 2], x)
    fb = sd(b[None, :, 0], b[None, :, 1], b[None, :, 2], x)
    m0 = 0.5 * (a[:, 0] + b[:, 0])
    m1 = 0.5 * (a[:, 1] + b[:, 1])
    m2 = 0.5 * (a[:, 2] + b[:, 2])
    fm = sd(m0[None, :], m1[None, :], m2[None, :], x)
    e0, e1, e2 = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1], b[:, 2] - a[:, 2]
    length = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    lower = 0.5 * (_lesser(fa, fb) + fm - 0.5 * length)
    best = _first_least(np.stack([fa, fb, fm], axis=2).reshape(n_d, 3 * n_s))
    # golden sections of every pair that could be minimised (the kernel decides below which)
    vals = _lesser(fa, fb)  # a segment no longer than tol: its ends' least value
    di, gi = np.nonzero(lower < best[:, None])
    short = length[gi] <= tol  # their golden section returns the ends' least value
    di, gi = di[~short], gi[~short]
    if di.size:
        per_segment = np.zeros(n_s, dtype=np.int64)
        for g in np.flatnonzero(np.bincount(gi, minlength=n_s)).tolist():  # libm's, as the kernel
            per_segment[g] = math.ceil(math.log(tol / float(length[g])) / math.log(inv_phi))
        steps = per_segment[gi]
        xa, d0, d1, d2 = depth[di], e0[gi], e1[gi], e2[gi]
        a0, a1, a2 = a[gi, 0], a[gi, 1], a[gi, 2]
        lo, hi = np.zeros(di.size), np.ones(di.size)
        c = hi - inv_phi * (hi - lo)
        d = lo + inv_phi * (hi - lo)
        fc = sd(a0 + c * d0, a1 + c * d1, a2 + c * d2, xa)
        fd = sd(a0 + d * d0, a1 + d * d1, a2 + d * d2, xa)
        for step in range(int(steps.max())):
            live = step < steps
            left = live & (fc <= fd)
            right = live & ~(fc <= fd)
            hi = np.where(left, d, hi)
            lo = np.where(right, c, lo)
            new_c = np.where(left, hi - inv_phi * (hi - lo), np.where(right, d, c))
            new_d = np.where(left, c, np.where(right, lo + inv_phi * (hi - lo), d))
            f_new_c = np.where(left, np.nan, np.where(right, fd, fc))
            f_new_d = np.where(left, fc, np.where(right, np.nan, fd))
            probe = np.where(left, new_c, new_d)
            f_probe = sd(a0 + probe * d0, a1 + probe * d1, a2 + probe * d2, xa)
            c, d = new_c, new_d
            fc = np.where(left, f_probe, f_new_c)
            fd = np.where(right, f_probe, f_new_d)
        vals[di, gi] = _lesser(_lesser(_lesser(fa, fb)[di, gi], fc), fd)
    # the kernel's pass: a segment whose bound is below the best so far (it only falls, so
    # only the segments of the pairs above can pass)
    for g in np.flatnonzero((lower < best[:, None]).any(axis=0)).tolist():
        best = np.where(lower[:, g] < best, _lesser(best, vals[:, g]), best)
    out[:] = best


def _first_least(values: np.ndarray) -> np.ndarray:
    """(D,) ``min(inf, v0, v1, ...)`` of each row taken one value at a time, as the kernel does:
    the first value equal to the least (its bits: -0.0 or 0.0), NaN never taken."""
    clean = np.where(np.isnan(values), np.inf, values)
    least = clean.min(axis=1, initial=np.inf)
    first = np.argmax(clean == least[:, None], axis=1)
    return clean[np.arange(values.shape[0]), first]
