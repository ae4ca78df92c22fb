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
minimum, and it is within ``tol_mm`` above it; the NumPy path's likewise: the two differ by at
most ``tol_mm`` (a few ulps where both reach the minimum exactly, at an end or a midpoint).
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
