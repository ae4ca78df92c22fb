"""A union of voxel boxes reduced exactly to segments for the distance to a solid on an axis.

A labelled voxel is a box of anatomy: the parallelepiped ``affine @ ([i, j, k] + [-1/2, 1/2]^3)``
on any grid (oblique and sheared affines included). The solid (the swept drill, an implant
body) is convex and a body of revolution around the trajectory's axis, so the signed distance
``sd`` from a point to it is convex and unchanged by rotations about the axis and by the
reflection in any plane through the axis. Where does ``sd`` reach its minimum over the union
``U`` of the boxes? Two facts, for a convex ``sd`` with these symmetries:

- **Rotation.** For a point ``p``, its half-turn ``p'`` about the axis has ``sd(p') = sd(p)``,
  so their midpoint, the foot of ``p`` on the axis, has ``sd <= sd(p)``. Along the segment
  from ``p`` to its foot ``sd`` never exceeds ``sd(p)`` (convexity): either the foot is in
  ``U`` (on an **axis chord** ``axis ∩ box``) or the segment leaves ``U`` through its
  boundary, at a point no worse than ``p``. So the minimum over ``U`` is reached on the axis
  chords or on the boundary of ``U``: its exposed faces (between a labelled and an unlabelled
  voxel), their edges and vertices.
- **Reflection.** On an exposed face's plane, the reflection in the plane through the axis
  that contains the face normal maps the face plane to itself and keeps ``sd``; it fixes the
  line where the two planes meet, the orthogonal projection of the axis on the face plane
  (the **axis shadow**). For ``p`` on the face, the midpoint of ``p`` and its mirror lies on
  the shadow with ``sd`` no larger, and along the segment to it ``sd`` never exceeds
  ``sd(p)``: either the midpoint is in the face (on the shadow **clipped to the face**) or the
  segment leaves the face through one of its edges. (A face normal along the axis has every
  plane through the axis as such a plane: its shadow is the axis' foot point, a chord end.)
- So the minimum over ``U`` is the minimum over the axis chords, the clipped axis shadows and
  every **exposed edge** (a grid edge with one to three of its four voxels labelled).

All these segments lie in ``U`` (none reports less than the truth) and none depends on the
depth the solid is placed at, nor on its shape: they are computed once per axis and measured
with :func:`ctdrill.imaging.plan.distance.segments_distance_mm`.
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.plan.distance import AxialSolid

_HALF = 0.5


def _clip(c0: np.ndarray, slope: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parameter interval where ``|c0 + s * slope| <= 1/2`` in every column.

    Parameters
    ----------
    c0 : (N, m) values at s = 0.
    slope : (m,) rate of change per unit s (shared by all rows).

    Returns
    -------
    s0, s1 : (N,) interval ends (0, 0 when no column constrains s).
    ok : (N,) the interval is not empty.
    """
    lo = np.full(len(c0), -np.inf)
    hi = np.full(len(c0), np.inf)
    ok = np.ones(len(c0), dtype=bool)
    scale = float(np.max(np.abs(slope))) or 1.0
    for m, rate in enumerate(slope.tolist()):
        if abs(rate) <= 1e-12 * scale:
            ok &= np.abs(c0[:, m]) <= _HALF
            continue
        a = (-_HALF - c0[:, m]) / rate
        b = (_HALF - c0[:, m]) / rate
        lo = np.maximum(lo, np.minimum(a, b))
        hi = np.minimum(hi, np.maximum(a, b))
    unbounded = ~np.isfinite(lo)
    lo = np.where(unbounded, 0.0, lo)
    hi = np.where(unbounded, 0.0, hi)
    return lo, hi, ok & (lo <= hi)


def _exposed_edges(mask: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Exposed grid edges as (start, end) index points (E, 3) in (i, j, k) order."""
    p = np.pad(mask, 1).astype(np.uint8)
    out: list[tuple[np.ndarray, np.ndarray]] = []
    # Edges along i: the four voxels around the line at the corner (kc, jc).
    cnt = p[:-1, :-1, 1:-1] + p[1:, :-1, 1:-1] + p[:-1, 1:, 1:-1] + p[1:, 1:, 1:-1]
    kc, jc, i = np.nonzero((cnt > 0) & (cnt < 4))
    mid = np.column_stack([i, jc - _HALF, kc - _HALF]).astype(np.float64)
    step = np.array([_HALF, 0, 0])
    out.append((mid - step, mid + step))
    cnt = p[:-1, 1:-1, :-1] + p[1:, 1:-1, :-1] + p[:-1, 1:-1, 1:] + p[1:, 1:-1, 1:]
    kc, j, ic = np.nonzero((cnt > 0) & (cnt < 4))
    mid = np.column_stack([ic - _HALF, j, kc - _HALF]).astype(np.float64)
    step = np.array([0, _HALF, 0])
    out.append((mid - step, mid + step))
    cnt = p[1:-1, :-1, :-1] + p[1:-1, 1:, :-1] + p[1:-1, :-1, 1:] + p[1:-1, 1:, 1:]
    k, jc, ic = np.nonzero((cnt > 0) & (cnt < 4))
    mid = np.column_stack([ic - _HALF, jc - _HALF, k]).astype(np.float64)
    step = np.array([0, 0, _HALF])
    out.append((mid - step, mid + step))
    return out


def exposed_face_centres(mask: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """Centres of the exposed faces as (axis, (F, 3) index points in (i, j, k) order)."""
    p = np.pad(mask, 1)
    inner = p[1:-1, 1:-1, 1:-1]
    out: list[tuple[int, np.ndarray]] = []
    # axis 0 = i (array axis 2), 1 = j (array axis 1), 2 = k (array axis 0)
    for axis, arr_axis in ((0, 2), (1, 1), (2, 0)):
        for step in (-1, 1):
            sl = [slice(1, -1)] * 3
            sl[arr_axis] = slice(1 + step, p.shape[arr_axis] - 1 + step)
            k, j, i = np.nonzero(inner & ~p[tuple(sl)])
            centre = np.column_stack([i, j, k]).astype(np.float64)
            centre[:, axis] += _HALF * step
            out.append((axis, centre))
    return out


def voxel_union_segments(
    mask: np.ndarray, affine_lps: np.ndarray, solid: AxialSolid
) -> tuple[np.ndarray, np.ndarray]:
    """Segments on which a solid's signed distance to the voxel union is minimal.

    Parameters
    ----------
    mask : (slices, rows, cols) bool, the labelled voxels.
    affine_lps : (4, 4) ``(i=col, j=row, k=slice, 1)`` to LPS mm; its 3x3 part invertible.
    solid : the drill or implant body (only its axis is used).

    Returns
    -------
    a, b : (S, 3) segment end points, LPS mm (see the module docstring).
    """
    aff = np.asarray(affine_lps, dtype=np.float64)
    lin, off = aff[:3, :3], aff[:3, 3]
    entry, d = solid.entry_lps, solid.direction
    starts: list[np.ndarray] = []
    ends: list[np.ndarray] = []
    for a_idx, b_idx in _exposed_edges(mask):
        starts.append(a_idx @ lin.T + off)
        ends.append(b_idx @ lin.T + off)
    # Axis shadows on the exposed faces.
    for axis, centres in exposed_face_centres(mask):
        if len(centres) == 0:
            continue
        span = lin[:, [m for m in range(3) if m != axis]]  # (3, 2) face edge vectors
        normal = np.cross(span[:, 0], span[:, 1])
        normal /= np.linalg.norm(normal)
        dual = np.linalg.pinv(span)  # (2, 3): rows lie in the face plane
        f_c = centres @ lin.T + off
        s0, s1, ok = _clip((entry - f_c) @ dual.T, dual @ d)
        f_c, s0, s1 = f_c[ok], s0[ok], s1[ok]
        for s, bucket in ((s0, starts), (s1, ends)):
            pt = entry + s[:, None] * d
            bucket.append(pt - ((pt - f_c) @ normal)[:, None] * normal)
    # Axis chords through every labelled voxel.
    kji = np.argwhere(mask)
    if len(kji):
        inv = np.linalg.inv(lin)
        centre_idx = kji[:, ::-1].astype(np.float64)
        s0, s1, ok = _clip((entry - off) @ inv.T - centre_idx, inv @ d)
        starts.append(entry + s0[ok, None] * d)
        ends.append(entry + s1[ok, None] * d)
    if not starts:
        return np.empty((0, 3)), np.empty((0, 3))
    return np.concatenate(starts), np.concatenate(ends)
