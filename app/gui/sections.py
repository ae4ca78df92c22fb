"""Where a plane cuts the plan's solids, headless and exact: what the slice views draw.

A plane is given by a point ``origin_lps``, in-plane unit vectors ``u_lps``, ``v_lps`` and
their normal ``n = u x v``; results are in-plane millimetres ``(u, v)`` from the origin (the
:class:`~ctdrill.app.gui.slices.SliceImage` convention).

Solids of revolution (the drill with its cone tip, an implant body) are a radius profile
``r(s)`` along an axis from ``p0``; the plane cuts the disc of radius ``r(s)`` at ``s`` in a
chord whose half-length has the closed form

    t(s) = sqrt(r(s)^2 - ((h + c s) / sigma)^2)

with ``h`` the signed distance of ``p0`` from the plane, ``c = axis . n`` and
``sigma = sqrt(1 - c^2)`` (the chord's midpoint lies on the line where the disc's plane meets
the view's). A cylinder seen across its axis is therefore an ellipse of semi-axes ``r`` and
``r / |c|``, seen along its axis a band ``2 sqrt(r^2 - h^2)`` wide, seen end on a circle. The
outline is traced at chords spaced by a cosine law between the exact ends of every piece, so
its vertices lie on the true boundary.

A tube around a polyline (the canal with its radius, its safety margin) is the set of points
within a distance of the polyline: :func:`polyline_distance_mm` gives that distance exactly on
a grid of in-plane points, for contouring.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

#: Chords traced per piece of a profile (cosine spaced).
CHORDS_PER_PIECE = 48
#: Below this sine of the angle between axis and plane, the axis is taken as normal to it.
END_ON_SIN = 1e-9


@dataclass(frozen=True, eq=False)
class Plane:
    """An oriented plane: a point and two in-plane unit vectors (LPS)."""

    origin_lps: np.ndarray
    u_lps: np.ndarray
    v_lps: np.ndarray

    @property
    def normal_lps(self) -> np.ndarray:
        """(3,) unit normal ``u x v``."""
        return cross3(self.u_lps, self.v_lps)

    def to_uv(self, points_lps: np.ndarray) -> np.ndarray:
        """(..., 3) LPS -> (..., 2) in-plane mm (the off-plane part dropped)."""
        rel = np.asarray(points_lps, dtype=np.float64) - self.origin_lps
        return np.stack([rel @ self.u_lps, rel @ self.v_lps], axis=-1)

    def to_lps(self, uv_mm: np.ndarray) -> np.ndarray:
        """(..., 2) in-plane mm -> (..., 3) LPS on the plane."""
        uv = np.asarray(uv_mm, dtype=np.float64)
        return np.asarray(self.origin_lps + uv[..., :1] * self.u_lps + uv[..., 1:2] * self.v_lps)


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3,) cross product of two (3,) vectors (``np.cross`` costs ~0.2 ms a call for its
    generality; a dragged outline takes several per repaint)."""
    a0, a1, a2 = (float(v) for v in a)
    b0, b1, b2 = (float(v) for v in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _profile_r(s: np.ndarray, s_knots: np.ndarray, r_knots: np.ndarray) -> np.ndarray:
    return np.asarray(np.interp(s, s_knots, r_knots), dtype=np.float64)


def revolved_section(
    plane: Plane,
    p0_lps: np.ndarray,
    axis_lps: np.ndarray,
    s_mm: np.ndarray,
    r_mm: np.ndarray,
    *,
    chords: int = CHORDS_PER_PIECE,
) -> list[np.ndarray]:
    """Outline(s) of the cut of a solid of revolution by ``plane``.

    Parameters
    ----------
    plane : the view plane.
    p0_lps : (3,) the axis point at ``s = 0``.
    axis_lps : (3,) the axis direction (normalised here).
    s_mm, r_mm : (K,) the radius profile, ``s`` non-decreasing along the axis, ``r >= 0``,
        linear between the knots; the solid spans ``s_mm[0]..s_mm[-1]``.
    chords : chords traced per piece.

    Returns
    -------
    list of (M, 2) closed outlines in in-plane mm (first vertex not repeated); empty when the
    plane misses the solid.
    """
    s_k = np.asarray(s_mm, dtype=np.float64)
    r_k = np.asarray(r_mm, dtype=np.float64)
    if s_k.ndim != 1 or s_k.shape != r_k.shape or s_k.size < 2 or np.any(np.diff(s_k) < 0):
        raise ValueError("profile: s_mm and r_mm need the same K >= 2 values, s non-decreasing")
    a = np.asarray(axis_lps, dtype=np.float64)
    a = a / np.linalg.norm(a)
    p0 = np.asarray(p0_lps, dtype=np.float64)
    n = plane.normal_lps
    c = float(a @ n)
    h = float((p0 - plane.origin_lps) @ n)
    sigma = float(np.sqrt(max(0.0, 1.0 - c * c)))
    if sigma < END_ON_SIN:  # the axis pierces the plane square on: a circle
        s_star = -h / c
        if not s_k[0] <= s_star <= s_k[-1]:
            return []
        radius = float(_profile_r(np.array(s_star), s_k, r_k))
        if radius <= 0.0:
            return []
        phi = np.linspace(0.0, 2.0 * np.pi, 4 * chords, endpoint=False)
        centre = plane.to_uv(p0 + s_star * a)
        return [centre + radius * np.stack([np.cos(phi), np.sin(phi)], axis=-1)]
    a_hat = (a - c * n) / sigma  # in-plane direction of the axis
    b = cross3(n, a_hat)  # in-plane, across the axis
    q_uv = plane.to_uv(p0 - h * n)
    along = np.array([a_hat @ plane.u_lps, a_hat @ plane.v_lps])
    across = np.array([b @ plane.u_lps, b @ plane.v_lps])

    # the knots: the profile's, where the axis crosses the plane, and where a segment's chord
    # closes (r(s) sigma = +-(h + c s), r(s) = r0 + k s on each segment)
    seg = s_k[1:] > s_k[:-1]
    k = (r_k[1:] - r_k[:-1])[seg] / (s_k[1:] - s_k[:-1])[seg]
    r0 = r_k[:-1][seg] - k * s_k[:-1][seg]
    nodes = [s_k, np.array([-h / c]) if c != 0.0 else np.empty(0)]
    for sign in (1.0, -1.0):
        den = k * sigma - sign * c
        nz = den != 0.0
        nodes.append((sign * h - r0[nz] * sigma) / den[nz])
    knots = np.unique(np.clip(np.concatenate(nodes), s_k[0], s_k[-1]))
    # every piece between knots at once: a piece has chords where r(s) sigma >= |h + c s| (at
    # its middle); its radius from its own profile segment (so a step in the profile, such as
    # a flat apex, keeps both its sides)
    s_a, s_b = knots[:-1], knots[1:]
    mid = 0.5 * (s_a + s_b)
    valid = ~(_profile_r(mid, s_k, r_k) * sigma - np.abs(h + c * mid) < 0.0)
    phi = np.linspace(0.0, np.pi, chords + 1)
    s_all = mid[:, None] - (0.5 * (s_b - s_a))[:, None] * np.cos(phi)[None, :]
    s_all[:, 0], s_all[:, -1] = s_a, s_b
    j = np.clip(np.searchsorted(s_k, mid, side="right") - 1, 0, s_k.size - 2)
    with np.errstate(divide="ignore", invalid="ignore"):  # pieces without chords: unused
        r_all = (
            r_k[j][:, None]
            + (r_k[j + 1] - r_k[j])[:, None]
            * (s_all - s_k[j][:, None])
            / (s_k[j + 1] - s_k[j])[:, None]
        )
    # runs of consecutive valid pieces, joined at their shared ends
    edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.view(np.int8), [0]])))
    runs = [
        (
            np.concatenate([s_all[i0], s_all[i0 + 1 : i1, 1:].ravel()]),
            np.concatenate([r_all[i0], r_all[i0 + 1 : i1, 1:].ravel()]),
        )
        for i0, i1 in zip(edges[::2], edges[1::2], strict=True)
    ]
    out = []
    for s, r in runs:
        t = np.sqrt(np.maximum(0.0, r**2 - ((h + c * s) / sigma) ** 2))
        w = (s + h * c) / sigma
        foot = q_uv + w[:, None] * along
        left, right = foot - t[:, None] * across, foot + t[:, None] * across
        outline = np.concatenate([left, right[::-1]])
        keep = np.ones(len(outline), dtype=bool)  # drop repeated vertices (t = 0 ends)
        keep[1:] = np.any(np.abs(np.diff(outline, axis=0)) > 1e-12, axis=1)
        if keep.sum() >= 3:
            out.append(outline[keep])
    return out


def cylinder_profile(length_mm: float, radius_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(s, r) of a cylinder of ``length_mm`` and ``radius_mm``."""
    return np.array([0.0, length_mm]), np.array([radius_mm, radius_mm])


def drill_profile(
    depth_mm: float, radius_mm: float, tip_length_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """(s, r) of a drill from the entry (s = 0) to its tip at ``depth_mm``: the body, then a
    cone of ``tip_length_mm`` (shortened to the depth when the drill is shallower)."""
    tip = min(max(tip_length_mm, 0.0), depth_mm)
    return (
        np.array([0.0, depth_mm - tip, depth_mm]),
        np.array([radius_mm, radius_mm, 0.0 if tip > 0.0 else radius_mm]),
    )


def polyline_distance_mm(points_lps: np.ndarray, polyline_lps: np.ndarray) -> np.ndarray:
    """Exact distance (..., ) from each point (..., 3) to a polyline (K, 3) (K = 1: a point)."""
    pts = np.asarray(points_lps, dtype=np.float64)
    line = np.atleast_2d(np.asarray(polyline_lps, dtype=np.float64))
    flat = pts.reshape(-1, 3)
    if len(line) == 1:
        return np.asarray(np.linalg.norm(flat - line[0], axis=1).reshape(pts.shape[:-1]))
    best = np.full(len(flat), np.inf)
    for p, q in itertools.pairwise(line):
        d = q - p
        dd = float(d @ d)
        t = np.zeros(len(flat)) if dd == 0.0 else np.clip((flat - p) @ d / dd, 0.0, 1.0)
        np.minimum(best, np.linalg.norm(flat - (p + t[:, None] * d), axis=1), out=best)
    return best.reshape(pts.shape[:-1])


def near_part(polyline_lps: np.ndarray, plane: Plane, reach_mm: float) -> np.ndarray:
    """(2M, 3) the ends, in pairs, of the M pieces of the polyline within ``reach_mm`` of the
    plane (its segments clipped to the slab); a one-point polyline: that point when within
    reach; (0, 3) when none is."""
    line = np.atleast_2d(np.asarray(polyline_lps, dtype=np.float64))
    n = plane.normal_lps
    d = (line - plane.origin_lps) @ n
    if len(line) == 1:
        return line if abs(float(d[0])) <= reach_mm else np.empty((0, 3))
    kept: list[np.ndarray] = []
    for p, q, dp, dq in zip(line[:-1], line[1:], d[:-1], d[1:], strict=True):
        lo, hi = 0.0, 1.0
        if dq != dp:  # clip t to |dp + t (dq - dp)| <= reach
            t1, t2 = (-reach_mm - dp) / (dq - dp), (reach_mm - dp) / (dq - dp)
            lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
        elif abs(dp) > reach_mm:
            continue
        if lo <= hi:
            kept.extend([p + lo * (q - p), p + hi * (q - p)])
    return np.array(kept).reshape(-1, 3)


#: Consecutive polyline pieces measured together over their common grid window.
PIECES_PER_WINDOW = 8


@dataclass(frozen=True, eq=False)
class TubeField:
    """Distance to a tube's centreline on an in-plane grid (for ``contour``/``contourf``)."""

    u_mm: np.ndarray  # (W,)
    v_mm: np.ndarray  # (H,)
    distance_mm: np.ndarray  # (H, W)


def tube_field(
    plane: Plane, polyline_lps: np.ndarray, reach_mm: float, step_mm: float
) -> TubeField | None:
    """The distance to ``polyline_lps`` over the part of ``plane`` within ``reach_mm`` of it
    (a grid of ``step_mm``, one step of border), or None when the tube misses the plane.

    Exact wherever it is at most ``reach_mm + 2 step_mm`` (so on both sides of every contour
    up to ``reach_mm``); elsewhere it holds that value, a lower bound. Each piece of the
    polyline near the plane is measured only over the grid window it can reach, a run of
    ``PIECES_PER_WINDOW`` consecutive pieces over their common window (one vectorised call
    each: a traced canal has tens of pieces, each a few ms of Python on its own)."""
    near = near_part(polyline_lps, plane, reach_mm)
    if len(near) == 0:
        return None
    uv = plane.to_uv(near)
    lo, hi = uv.min(axis=0) - reach_mm - step_mm, uv.max(axis=0) + reach_mm + step_mm
    u = np.arange(lo[0], hi[0] + step_mm, step_mm)
    v = np.arange(lo[1], hi[1] + step_mm, step_mm)
    far = reach_mm + 2.0 * step_mm
    dist = np.full((len(v), len(u)), far)
    starts, ends = (near[:1], near[:1]) if len(near) == 1 else (near[0::2], near[1::2])
    for g in range(0, len(starts), PIECES_PER_WINDOW):
        a, b = starts[g : g + PIECES_PER_WINDOW], ends[g : g + PIECES_PER_WINDOW]
        box = plane.to_uv(np.concatenate([a, b]))
        i0, j0 = (
            np.searchsorted(u, box[:, 0].min() - far),
            np.searchsorted(v, box[:, 1].min() - far),
        )
        i1 = np.searchsorted(u, box[:, 0].max() + far, side="right")
        j1 = np.searchsorted(v, box[:, 1].max() + far, side="right")
        if i0 >= i1 or j0 >= j1:
            continue
        grid = np.stack(np.meshgrid(u[i0:i1], v[j0:j1]), axis=-1)
        d = segments_distance_mm(plane.to_lps(grid), a, b)
        np.minimum(dist[j0:j1, i0:i1], d.reshape(grid.shape[:2]), out=dist[j0:j1, i0:i1])
    return TubeField(u_mm=u, v_mm=v, distance_mm=dist)


def segments_distance_mm(
    points_lps: np.ndarray, a_lps: np.ndarray, b_lps: np.ndarray, *, chunk: int = 16384
) -> np.ndarray:
    """(N,) exact distance from each point (N, 3) to the nearest of the segments
    ``a_lps[s]``-``b_lps[s]`` (S, 3), vectorised over points and segments."""
    a, b = np.asarray(a_lps, dtype=np.float64), np.asarray(b_lps, dtype=np.float64)
    centre = a[0].copy()  # local coordinates: no cancellation far from the origin
    pts = np.asarray(points_lps, dtype=np.float64).reshape(-1, 3) - centre
    a, b = a - centre, b - centre
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    safe = np.where(dd > 0.0, dd, 1.0)
    out = np.empty(len(pts))
    for lo in range(0, len(pts), chunk):
        p = pts[lo : lo + chunk]
        rel_d = p @ d.T - np.einsum("ij,ij->i", a, d)  # (P - a) . d, (n, S)
        t = np.where(dd > 0.0, np.clip(rel_d / safe, 0.0, 1.0), 0.0)
        rel2 = (
            np.einsum("ij,ij->i", p, p)[:, None] - 2.0 * p @ a.T + np.einsum("ij,ij->i", a, a)
        )  # |P - a|^2
        dist2 = rel2 - 2.0 * t * rel_d + t * t * dd
        out[lo : lo + chunk] = np.sqrt(np.maximum(dist2.min(axis=1), 0.0))
    return out


def in_plane_distance_mm(a_lps: np.ndarray, b_lps: np.ndarray) -> float:
    """Length of a measured segment, mm (both ends on the plane: exact in LPS)."""
    return float(np.linalg.norm(np.asarray(b_lps, float) - np.asarray(a_lps, float)))
