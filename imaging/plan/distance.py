"""Exact signed distances to the swept drill solid and the implant body (pure NumPy, no I/O).

Both are convex solids of revolution about a trajectory's axis, measured by the one routine
of :mod:`ctdrill.imaging.plan.revolution`; what this module adds is the minimum of that
distance over segments (a landmark's centreline, a point, a mask's candidate segments), which
holds for any convex solid on the axis (:class:`AxialSolid`).

The drill solid at tip depth ``x`` is the body of revolution around the drill axis whose
meridian section is ``{(s, rho): s <= x, rho <= R * min(1, (x - s) / l_t)}``: a cylinder of
radius ``R`` from far outside (``s -> -inf``) to ``s = x - l_t``, then a cone of length ``l_t``
ending at the tip point ``(x, 0)``. ``s`` is the axial coordinate from the entry point along
the drill direction (mm) and ``rho`` the distance from the axis (mm). The meridian section is
convex, so the solid is convex and the distance from a point to it is the 2-D distance from
``(s, rho)`` to the section's boundary (the cylinder ray and the cone segment).

Distances are **signed**: negative inside the solid (minus the distance to its surface), so
a landmark the drill enters has a negative clearance however thin it is. The signed distance
to a convex set is a convex function of the point, and it only decreases as the tip advances
(the solid grows), which the segment minimisation and the safe-depth search rely on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ctdrill.imaging.plan.revolution import Meridian, drill_meridian
from ctdrill.imaging.plan.segments_kernel import SEGMENTS_KERNEL, meridian_rows, segments_numpy

#: Accuracy of the segment minimisation, mm: golden-section steps continue until the bracket
#: times the segment length (the Lipschitz bound of the distance) is below it.
SEGMENT_TOL_MM = 1e-7
_INV_PHI = float((np.sqrt(5.0) - 1.0) / 2.0)
#: Elements per temporary (depths x segments) array: bounds memory for any landmark size.
_CHUNK_ELEMENTS = 1 << 18
#: Segments per block of the coarse pruning pass (used above 16 blocks).
_BLOCK = 64


class AxialSolid(Protocol):
    """A convex solid of revolution about an axis, placed by a depth along it: the swept drill
    (:class:`DrillSolid`, tip at the depth) or an implant body (its apex at the depth,
    :class:`~ctdrill.imaging.plan.implant_body.ImplantBody`). Landmarks measure their
    clearance to any of them (:meth:`~ctdrill.imaging.plan.landmark_base.Landmark.clearance_mm`).
    """

    @property
    def entry_lps(self) -> np.ndarray:
        """(3,) LPS mm, depth 0 of the axis."""
        ...

    @property
    def direction(self) -> np.ndarray:
        """(3,) unit vector along the axis (entry to target)."""
        ...

    def signed_distance_mm(self, points_lps: np.ndarray, depth_mm: np.ndarray) -> np.ndarray:
        """Signed distance (mm, < 0 inside) from points (..., 3) to the solid placed at
        ``depth_mm`` (broadcast with the points' batch shape)."""
        ...


@dataclass(frozen=True, eq=False)
class DrillSolid:
    """The drill axis and shape: entry point (depth 0), unit direction, radius, cone length.

    All in LPS mm; ``tip_length_mm`` may be 0 (a flat-ended drill).
    """

    entry_lps: np.ndarray
    direction: np.ndarray
    radius_mm: float
    tip_length_mm: float
    meridian: Meridian = field(init=False, repr=False)

    def __post_init__(self) -> None:
        entry = np.array(self.entry_lps, dtype=np.float64).reshape(3)
        u = np.array(self.direction, dtype=np.float64).reshape(3)
        norm = float(np.linalg.norm(u))
        if not (np.all(np.isfinite(entry)) and math.isfinite(norm) and norm > 0.0):
            raise ValueError("drill axis: entry and direction must be finite, direction non-zero")
        u = u / norm
        if not (self.radius_mm > 0.0 and self.tip_length_mm >= 0.0):
            raise ValueError(
                f"drill: the radius must be > 0 mm and the tip length >= 0 mm, got "
                f"{self.radius_mm!r}, {self.tip_length_mm!r}"
            )
        for name, arr in (("entry_lps", entry), ("direction", u)):
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "meridian", drill_meridian(self.radius_mm, self.tip_length_mm))

    def signed_distance_mm(self, points_lps: np.ndarray, depth_mm: np.ndarray) -> np.ndarray:
        """Signed distance from points (..., 3) LPS mm to the solid at tip depth ``depth_mm``
        (broadcast), mm."""
        s, perp = axial_coordinates(points_lps, self.entry_lps, self.direction)
        return self.meridian.signed_distance_mm(
            s - np.asarray(depth_mm, dtype=np.float64), np.linalg.norm(perp, axis=-1)
        )


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
    """Exact signed distance from points to the drill solid at tip depth ``depth_mm``.

    Parameters
    ----------
    s_mm, rho_mm : broadcastable arrays; axial coordinate and distance from the axis, mm.
    depth_mm : tip depth, broadcastable with ``s_mm``, mm.
    radius_mm : drill radius ``R``, mm (> 0).
    tip_length_mm : cone length ``l_t``, mm (>= 0).

    Returns
    -------
    Signed distance, mm: > 0 outside, 0 on the surface, minus the distance to the surface
    inside (down to ``-R`` on the axis of the cylinder); shape of the broadcast inputs.
    """
    u = np.asarray(s_mm, dtype=np.float64) - np.asarray(depth_mm, dtype=np.float64)
    return drill_meridian(radius_mm, tip_length_mm).signed_distance_mm(u, rho_mm)


def _golden_min(solid: AxialSolid, a: np.ndarray, b: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(P,) minimum over each segment ``[a_p, b_p]`` of the signed distance at ``depth_p``.

    The signed distance to a convex solid is convex along a segment, so a golden-section
    search on the segment parameter brackets the minimiser; it runs until the bracket times
    the longest ``|b - a|`` is below :data:`SEGMENT_TOL_MM` (the distance is
    ``|b - a|``-Lipschitz in the parameter, so the value is within that of the minimum).
    """
    dv = b - a
    length = float(np.linalg.norm(dv, axis=-1).max()) if len(a) else 0.0

    def f(t: np.ndarray) -> np.ndarray:
        return solid.signed_distance_mm(a + t[:, None] * dv, depth)

    best = np.minimum(f(np.zeros(len(a))), f(np.ones(len(a))))
    if length <= SEGMENT_TOL_MM:
        return best
    lo = np.zeros(len(a))
    hi = np.ones(len(a))
    c = hi - _INV_PHI * (hi - lo)
    d = lo + _INV_PHI * (hi - lo)
    fc = f(c)
    fd = f(d)
    steps = math.ceil(math.log(SEGMENT_TOL_MM / length, _INV_PHI))
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
    out: np.ndarray = np.minimum(best, np.minimum(fc, fd))
    return out


def segments_distance_mm(
    a_lps: np.ndarray, b_lps: np.ndarray, depth_mm: np.ndarray, solid: AxialSolid
) -> np.ndarray:
    """Signed distance from the union of segments ``[a, b]`` to a solid at each depth.

    The minimum over the union is exact to :data:`SEGMENT_TOL_MM` (see :func:`_golden_min`).
    For a solid with a meridian (the drill, an implant body) the compiled kernel of
    :mod:`ctdrill.imaging.plan.segments_kernel` computes it when its cache is present, else its
    NumPy twin with the same bits; other solids, and the tests' reference, take
    :func:`golden_segments_distance_mm`.
    Segments that cannot hold the minimum are skipped exactly: the signed distance is
    1-Lipschitz in space, which bounds a segment's minimum from below by its values at the
    ends and the midpoint, and it is skipped when that bound exceeds a value already reached.
    Work is done in chunks of at most ``2**18`` (depth, segment) pairs, so memory stays
    bounded for any number of segments (a 200 000-point canal, a large mask).

    Parameters
    ----------
    a_lps, b_lps : (S, 3) segment end points, LPS mm (``a == b`` is a point).
    depth_mm : (D,) depths where the solid is placed (the drill's tip, an implant's apex), mm.
    solid : the drill or implant on its axis (any convex :class:`AxialSolid`).

    Returns
    -------
    (D,) signed distance to the nearest segment, mm (+inf when there is no segment).
    """
    a = np.asarray(a_lps, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(b_lps, dtype=np.float64).reshape(-1, 3)
    x = np.asarray(depth_mm, dtype=np.float64).reshape(-1)
    best = np.full(x.shape, np.inf)
    if len(a) == 0 or x.size == 0:
        return best
    if len(a) > _BLOCK * 16:
        keep = _near_segments(a, b, x, solid)
        a, b = a[keep], b[keep]
    meridian = getattr(solid, "meridian", None)
    if isinstance(meridian, Meridian):
        # point by point (:mod:`ctdrill.imaging.plan.segments_kernel`): compiled where loaded,
        # else its NumPy twin, the same bits
        args = (
            meridian_rows(meridian),
            np.ascontiguousarray(solid.entry_lps, dtype=np.float64),
            np.ascontiguousarray(solid.direction, dtype=np.float64),
            np.ascontiguousarray(a),
            np.ascontiguousarray(b),
        )
        if SEGMENTS_KERNEL.ready():
            SEGMENTS_KERNEL(*args, np.ascontiguousarray(x), SEGMENT_TOL_MM, _INV_PHI, best)
        else:
            for lo in range(0, x.size, max(1, _CHUNK_ELEMENTS // len(a))):
                part = x[lo : lo + max(1, _CHUNK_ELEMENTS // len(a))]
                segments_numpy(*args, part, SEGMENT_TOL_MM, _INV_PHI, best[lo : lo + part.size])
        return best
    return golden_segments_distance_mm(a, b, x, solid)


def golden_segments_distance_mm(
    a: np.ndarray, b: np.ndarray, x: np.ndarray, solid: AxialSolid
) -> np.ndarray:
    """:func:`segments_distance_mm` by golden section on every segment at once (any
    :class:`AxialSolid`; the reference the kernel and its twin are tested against: within
    :data:`SEGMENT_TOL_MM`). ``a``, ``b`` (S, 3), ``x`` (D,) as there, float64."""
    best = np.full(x.shape, np.inf)
    if len(a) == 0 or x.size == 0:
        return best
    per = max(1, _CHUNK_ELEMENTS // x.size)
    half = 0.5 * np.linalg.norm(b - a, axis=-1)

    def ends(sl: slice) -> tuple[np.ndarray, np.ndarray]:
        """(D, c) min of the three probe values and the 1-Lipschitz lower bound."""
        va = solid.signed_distance_mm(a[sl][None, :, :], x[:, None])
        vb = solid.signed_distance_mm(b[sl][None, :, :], x[:, None])
        vm = solid.signed_distance_mm((0.5 * (a[sl] + b[sl]))[None, :, :], x[:, None])
        upper = np.minimum(np.minimum(va, vb), vm)
        # On a half of length L/2 between values u and v, a 1-Lipschitz function stays above
        # (u + v - L/2) / 2: the segment's lower bound is the smaller of its halves' bounds.
        lower = 0.5 * (np.minimum(va, vb) + vm - half[sl][None, :])
        return upper, lower

    starts = range(0, len(a), per)
    first = ends(slice(0, per))  # one chunk (the usual case): computed once, used twice
    for start in starts:
        upper, _ = first if start == 0 else ends(slice(start, start + per))
        best = np.minimum(best, upper.min(axis=1))
    for start in starts:
        sl = slice(start, start + per)
        _, lower = first if start == 0 else ends(sl)
        di, si = np.nonzero(lower < best[:, None])
        si += start
        for p in range(0, di.size, _CHUNK_ELEMENTS // 8):
            dd, ss = di[p : p + _CHUNK_ELEMENTS // 8], si[p : p + _CHUNK_ELEMENTS // 8]
            np.minimum.at(best, dd, _golden_min(solid, a[ss], b[ss], x[dd]))
    return best


def _morton_order(points: np.ndarray) -> np.ndarray:
    """Indices sorting ``points`` (N, 3) along a Z-order curve (10 bits per axis)."""
    lo = points.min(axis=0)
    span = float((points.max(axis=0) - lo).max()) or 1.0
    q = ((points - lo) / span * 1023.0).astype(np.uint64)
    key = np.zeros(len(points), dtype=np.uint64)
    for bit in range(10):
        for axis in range(3):
            key |= ((q[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return np.argsort(key, kind="stable")


def _near_segments(a: np.ndarray, b: np.ndarray, x: np.ndarray, solid: AxialSolid) -> np.ndarray:
    """Indices of the segments that may hold the minimum at some depth (exact pruning).

    Segments are grouped in blocks of :data:`_BLOCK` along a Z-order curve; a block's
    bounding sphere (centre ``c``, radius ``r``) bounds its distance from below by
    ``sd(c) - r`` (the signed distance is 1-Lipschitz) and any of its end points bounds the
    minimum from above; blocks whose lower bound exceeds that minimum at every depth are
    dropped.
    """
    order = _morton_order(0.5 * (a + b))
    n_blocks = -(-len(order) // _BLOCK)
    pad = np.concatenate([order, np.full(n_blocks * _BLOCK - len(order), order[-1])])
    blocks = pad.reshape(n_blocks, _BLOCK)
    ends = np.concatenate([a[blocks], b[blocks]], axis=1)  # (B, 2 * BLOCK, 3)
    centre = 0.5 * (ends.min(axis=1) + ends.max(axis=1))
    radius = np.linalg.norm(ends - centre[:, None, :], axis=-1).max(axis=1)
    upper = np.full(x.shape, np.inf)
    lower = np.empty((x.size, n_blocks))
    per = max(1, _CHUNK_ELEMENTS // x.size)
    for start in range(0, n_blocks, per):
        sl = slice(start, start + per)
        upper = np.minimum(
            upper, solid.signed_distance_mm(ends[sl, 0][None], x[:, None]).min(axis=1)
        )
        lower[:, sl] = solid.signed_distance_mm(centre[sl][None], x[:, None]) - radius[sl][None, :]
    near = np.any(lower <= upper[:, None], axis=0)
    return np.unique(blocks[near])


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
    """:func:`segments_distance_mm` with the drill given by its parts (signed, (D,) mm)."""
    solid = DrillSolid(entry_lps, direction, radius_mm, tip_length_mm)
    return segments_distance_mm(a_lps, b_lps, depth_mm, solid)
