"""Exact distances to the swept drill solid (pure NumPy, no I/O).

The drill solid at tip depth ``x`` is the body of revolution around the drill axis whose
meridian section is ``{(s, rho): s <= x, rho <= R * min(1, (x - s) / l_t)}``: a cylinder of
radius ``R`` from far outside (``s -> -inf``) to ``s = x - l_t``, then a cone of length ``l_t``
ending at the tip point ``(x, 0)``. ``s`` is the axial coordinate from the entry point along
the drill direction (mm) and ``rho`` the distance from the axis (mm). The meridian section is
convex, so the solid is convex and the distance from a point to it is the 2-D distance from
``(s, rho)`` to the section's boundary (the cylinder ray and the cone segment).
"""

from __future__ import annotations

import math

import numpy as np

#: Accuracy of the segment minimisation, mm: golden-section steps continue until the bracket
#: times the segment length (the Lipschitz bound of the distance) is below it.
SEGMENT_TOL_MM = 1e-7
_INV_PHI = (np.sqrt(5.0) - 1.0) / 2.0


def axial_coordinates(
    points_lps: np.ndarray, entry_lps: np.ndarray, direction: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Axial coordinate and perpendicular offset of points relative to the drill axis.

    Parameters
    ----------
    points_lps : (..., 3) LPS mm.
    entry_lps : (3,) LPS mm, depth 0 of the axis.
    direction : (3,) unit vector from entry to target.

    Returns
    -------
    s_mm : (...,) axial coordinate, mm (depth along the axis).
    perp_mm : (..., 3) component perpendicular to the axis, mm.
    """
    rel = np.asarray(points_lps, dtype=np.float64) - entry_lps
    s_mm = rel @ direction
    perp_mm = rel - s_mm[..., None] * direction
    return s_mm, perp_mm


def solid_distance_mm(
    s_mm: np.ndarray,
    rho_mm: np.ndarray,
    depth_mm: np.ndarray | float,
    *,
    radius_mm: float,
    tip_length_mm: float,
) -> np.ndarray:
    """Exact Euclidean distance from points to the drill solid at tip depth ``depth_mm``.

    Parameters
    ----------
    s_mm, rho_mm : broadcastable arrays; axial coordinate and distance from the axis, mm.
    depth_mm : tip depth, broadcastable with ``s_mm``, mm.
    radius_mm : drill radius ``R``, mm (> 0).
    tip_length_mm : cone length ``l_t``, mm (>= 0).

    Returns
    -------
    Distance, mm, >= 0 (0 inside the solid); shape of the broadcast inputs.
    """
    s = np.asarray(s_mm, dtype=np.float64)
    rho = np.abs(np.asarray(rho_mm, dtype=np.float64))
    x = np.asarray(depth_mm, dtype=np.float64)
    corner_s = x - tip_length_mm
    # Cylinder side: the ray {(t, R): t <= corner_s}.
    d_ray = np.hypot(np.maximum(s - corner_s, 0.0), rho - radius_mm)
    # Cone side: the segment from the corner (corner_s, R) to the tip (x, 0).
    seg_len2 = tip_length_mm**2 + radius_mm**2
    ds = s - corner_s
    dr = rho - radius_mm
    t = np.clip((ds * tip_length_mm - dr * radius_mm) / seg_len2, 0.0, 1.0)
    d_cone = np.hypot(ds - t * tip_length_mm, dr + t * radius_mm)
    # Inside: s <= x and rho * l_t <= R * (x - s) and rho <= R (no division, l_t may be 0).
    inside = (s <= x) & (rho <= radius_mm) & (rho * tip_length_mm <= radius_mm * (x - s))
    out: np.ndarray = np.where(inside, 0.0, np.minimum(d_ray, d_cone))
    return out


def segment_solid_distance_mm(
    a_lps: np.ndarray,
    b_lps: np.ndarray,
    depth_mm: np.ndarray,
    *,
    entry_lps: np.ndarray,
    direction: np.ndarray,
    radius_mm: float,
    tip_length_mm: float,
) -> np.ndarray:
    """Distance from the union of segments ``[a, b]`` to the drill solid at each depth.

    The distance from a point moving along a segment to a convex solid is a convex function
    of the segment parameter, so a golden-section search on ``[0, 1]`` brackets the minimiser;
    it runs until the bracket times ``|b - a|`` is below :data:`SEGMENT_TOL_MM`, and as the
    distance is ``|b - a|``-Lipschitz in the parameter the value is then within 1e-7 mm of the
    exact minimum. Segments that cannot hold the minimum are skipped exactly: the distance
    is 1-Lipschitz in space, which bounds a segment's minimum from below by its values at the
    ends and the midpoint, and it is skipped when that bound exceeds a distance already
    reached.

    Parameters
    ----------
    a_lps, b_lps : (S, 3) segment end points, LPS mm (``a == b`` is a point).
    depth_mm : (D,) tip depths, mm.
    entry_lps, direction : the drill axis (entry point, unit direction).
    radius_mm, tip_length_mm : drill radius and cone length, mm.

    Returns
    -------
    (D,) distance to the nearest segment, mm, >= 0.
    """
    sa, pa = axial_coordinates(a_lps, entry_lps, direction)
    sb, pb = axial_coordinates(b_lps, entry_lps, direction)
    x = np.asarray(depth_mm, dtype=np.float64)
    half = 0.5 * np.linalg.norm(np.asarray(b_lps, float) - np.asarray(a_lps, float), axis=-1)

    def f_all(t: float) -> np.ndarray:
        """(D, S) distance at parameter t of every segment."""
        rho = np.linalg.norm(pa + t * (pb - pa), axis=-1)
        return solid_distance_mm(
            (sa + t * (sb - sa))[None, :],
            rho[None, :],
            x[:, None],
            radius_mm=radius_mm,
            tip_length_mm=tip_length_mm,
        )

    d_a, d_mid, d_b = f_all(0.0), f_all(0.5), f_all(1.0)
    upper = np.minimum(np.minimum(d_a, d_b), d_mid).min(axis=1)  # (D,)
    # On a half of length L/2 between values u and v, a 1-Lipschitz function stays above
    # (u + v - L/2) / 2: the segment's lower bound is the smaller of its halves' bounds.
    lower = 0.5 * (np.minimum(d_a, d_b) + d_mid - half[None, :])
    di, si = np.nonzero(lower < upper[:, None])
    best = upper.copy()
    if di.size == 0:
        return best
    sa_p, sb_p, pa_p, dp_p, x_p = sa[si], sb[si], pa[si], (pb - pa)[si], x[di]

    def f(t: np.ndarray) -> np.ndarray:
        rho = np.linalg.norm(pa_p + t[:, None] * dp_p, axis=-1)
        return solid_distance_mm(
            sa_p + t * (sb_p - sa_p), rho, x_p, radius_mm=radius_mm, tip_length_mm=tip_length_mm
        )

    lo = np.zeros(di.size)
    hi = np.ones(di.size)
    c = hi - _INV_PHI * (hi - lo)
    d = lo + _INV_PHI * (hi - lo)
    fc = f(c)
    fd = f(d)
    longest = float(2.0 * half[si].max())
    steps = (
        0 if longest <= SEGMENT_TOL_MM else math.ceil(math.log(SEGMENT_TOL_MM / longest, _INV_PHI))
    )
    for _ in range(steps):
        left = fc <= fd  # convexity: a minimiser lies in [lo, d], else in [c, hi]
        hi = np.where(left, d, hi)
        lo = np.where(left, lo, c)
        keep = np.where(left, c, d)  # the interior point that survives
        f_keep = np.where(left, fc, fd)
        probe = np.where(left, hi - _INV_PHI * (hi - lo), lo + _INV_PHI * (hi - lo))
        f_probe = f(probe)
        c, fc = np.where(left, probe, keep), np.where(left, f_probe, f_keep)
        d, fd = np.where(left, keep, probe), np.where(left, f_keep, f_probe)
    np.minimum.at(best, di, np.minimum(fc, fd))
    return best
