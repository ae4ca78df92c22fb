"""The dental arch as a curve in the axial plane: arc length, smoothed normals, projection.

A panoramic reformat is a vertical "curtain" standing on the arch (DESIGN.md 2: LPS mm, +z is
patient superior). Its geometry, owned here:

- **The curve.** The arch polyline ``arch_lps`` (K, 3) is projected on the axial plane (its
  ``z`` dropped): planners draw the arch on an axial slice, and every row of the panorama is a
  constant ``z``, so the panorama is upright whatever the points' heights. Consecutive points
  that coincide in that projection add no length and are dropped (exact, nothing guessed).
  ``s`` is the arc length (mm) along the projected polyline from its first point; ``point(s)``
  is the exact position on it (linear along each segment).
- **The tangent, smoothed.** A polyline's tangent jumps at every vertex, and normals built
  from it would jump too (the panorama would tear or repeat columns there). The tangent used
  here is the *mean unit tangent over an arc window* of ``window_mm`` centred on ``s``
  (clamped at the two ends), which in closed form is the chord
  ``point(s + w/2) - point(s - w/2)`` normalised: it turns continuously through each vertex
  over ``window_mm`` of arc and equals the segment direction farther than ``window_mm / 2``
  from any vertex. Through a vertex of exterior angle ``a`` (vertices more than ``window_mm``
  apart) it turns by ``a`` in all, at most ``2 tan(a / 2) / window_mm`` rad per mm. The
  bucco-lingual **normal** is ``ez x tangent`` (horizontal, to the
  tangent's left seen from above).
- **Projection.** A point ``P`` sits on the curtain at arc ``s`` when its horizontal offset
  from ``point(s)`` is along the normal: ``g(s) = (P - point(s)) . tangent(s) = 0``. The roots
  are bracketed on a fine grid and bisected to 1e-9 mm; of several roots (far from a concave
  arch, normals cross) the one nearest the curtain is kept. A point whose normal foot lies
  beyond the arch's ends has no root and projects to NaN.

Normals fold (two columns' slab samples cross) only beyond the smoothed curve's radius of
curvature; :meth:`ArchCurve.min_radius_mm` reports it.
"""

from __future__ import annotations

import bisect
import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ctdrill.imaging.errors import ImagingInputError

#: Default arc window (mm) over which the tangent is averaged.
TANGENT_WINDOW_MM = 10.0
#: Grid step (mm) on which projection roots are bracketed, at most.
_ROOT_GRID_MM = 0.25
#: Bisection steps: 120 mm / 2**40 ~ 1e-10 mm.
_BISECT_STEPS = 48
#: |g| (mm) below which a point counts as exactly on a grid column's normal (rounding).
_ZERO_MM = 1e-9
#: Points per projection chunk (bounded memory: chunk x grid evaluations at once).
_PROJECT_CHUNK = 2048
#: An arch whose centroid lies within this distance (mm) of its own normal line is straight
#: there: it has no inside, so no buccal or lingual side.
STRAIGHT_MM = 1e-6


class ArchInputError(ImagingInputError):
    """The arch polyline cannot carry a reformat."""


@dataclass(frozen=True, eq=False)
class ArchCurve:
    """The arch's axial projection with arc length, smoothed tangents and normals.

    Attributes
    ----------
    arch_lps : np.ndarray
        (K, 3) the arch as given, LPS mm (read-only).
    window_mm : float
        Arc window (mm) of the tangent's averaging; see the module docstring.
    """

    arch_lps: np.ndarray
    window_mm: float = TANGENT_WINDOW_MM
    _xy: np.ndarray = field(init=False, repr=False)
    _z: np.ndarray = field(init=False, repr=False)
    _cum: np.ndarray = field(init=False, repr=False)
    _cum_list: list[float] = field(init=False, repr=False)
    _xy_list: list[tuple[float, float]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        arch = np.array(self.arch_lps, dtype=np.float64)
        if arch.ndim != 2 or arch.shape[1] != 3 or arch.shape[0] < 2:
            raise ArchInputError(
                f"arch: expected (K, 3) LPS points with K >= 2, got shape {arch.shape}; "
                "draw the arch with at least two points"
            )
        if not np.all(np.isfinite(arch)):
            raise ArchInputError("arch: points must be finite numbers")
        if not (np.isfinite(self.window_mm) and self.window_mm >= 0.0):
            raise ArchInputError(f"arch: tangent window {self.window_mm!r} mm must be >= 0")
        xy = arch[:, :2]
        keep = np.ones(len(xy), dtype=bool)
        keep[1:] = np.linalg.norm(np.diff(xy, axis=0), axis=1) > 1e-9
        xy = xy[keep]
        z = arch[keep, 2]
        if len(xy) < 2:
            raise ArchInputError(
                "arch: all its points lie on one vertical line (no length in the axial plane); "
                "draw the arch on an axial slice along the teeth or the alveolar ridge"
            )
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
        arch.flags.writeable = False
        xy.flags.writeable = False
        cum.flags.writeable = False
        object.__setattr__(self, "arch_lps", arch)
        object.__setattr__(self, "window_mm", float(self.window_mm))
        object.__setattr__(self, "_xy", xy)
        object.__setattr__(self, "_z", z)
        object.__setattr__(self, "_cum", cum)
        object.__setattr__(self, "_cum_list", cum.tolist())
        object.__setattr__(self, "_xy_list", [tuple(p) for p in xy.tolist()])
        # A hairpin within the window makes the chord vanish: refuse, never divide by ~0.
        grid = self.grid_mm(_ROOT_GRID_MM)
        chord = self._chord(grid)
        if np.min(np.linalg.norm(chord, axis=1)) < 1e-6 * max(self.window_mm, 1e-3):
            raise ArchInputError(
                "arch: it folds back on itself within the tangent window "
                f"({self.window_mm:g} mm); draw it without sharp reversals"
            )

    @property
    def length_mm(self) -> float:
        """Arc length of the axial projection, mm."""
        return float(self._cum[-1])

    @property
    def mean_z_mm(self) -> float:
        """Mean LPS z of the arch's points, mm (where the arch was drawn)."""
        return float(np.mean(self.arch_lps[:, 2]))

    def grid_mm(self, step_mm: float) -> np.ndarray:
        """Arc positions from 0 to the length, spaced at most ``step_mm``, ends included."""
        n = max(2, int(np.ceil(self.length_mm / step_mm)) + 1)
        return np.linspace(0.0, self.length_mm, n)

    def point_xy(self, s_mm: np.ndarray) -> np.ndarray:
        """(..., 2) exact position on the projected polyline at arc ``s_mm`` (clamped)."""
        s = np.clip(np.asarray(s_mm, dtype=np.float64), 0.0, self.length_mm)
        seg = np.clip(np.searchsorted(self._cum, s, side="right") - 1, 0, len(self._cum) - 2)
        seg_len = self._cum[seg + 1] - self._cum[seg]
        f = (s - self._cum[seg]) / seg_len
        return np.asarray(self._xy[seg] + f[..., None] * (self._xy[seg + 1] - self._xy[seg]))

    def point_z(self, s_mm: np.ndarray) -> np.ndarray:
        """(...) the arch's own height (LPS z, mm) at arc ``s_mm``, linear between its points."""
        s = np.clip(np.asarray(s_mm, dtype=np.float64), 0.0, self.length_mm)
        return np.asarray(np.interp(s, self._cum, self._z))

    def _chord(self, s_mm: np.ndarray) -> np.ndarray:
        half = 0.5 * self.window_mm
        s = np.asarray(s_mm, dtype=np.float64)
        if half == 0.0:
            seg = np.clip(np.searchsorted(self._cum, s, side="right") - 1, 0, len(self._cum) - 2)
            return np.asarray(self._xy[seg + 1] - self._xy[seg])
        return self.point_xy(s + half) - self.point_xy(s - half)

    def tangent_xy(self, s_mm: np.ndarray) -> np.ndarray:
        """(..., 2) unit tangent averaged over the arc window centred on ``s_mm``."""
        chord = self._chord(s_mm)
        return np.asarray(chord / np.linalg.norm(chord, axis=-1, keepdims=True))

    def frame(self, s_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Origin (..., 3) at height 0, tangent (..., 3) and normal (..., 3) at arc ``s_mm``.

        The origin is the curve point with z = 0; tangent and normal are horizontal unit
        vectors, ``normal = ez x tangent``.
        """
        p = self.point_xy(s_mm)
        t = self.tangent_xy(s_mm)
        zeros = np.zeros((*p.shape[:-1], 1))
        origin = np.concatenate([p, zeros], axis=-1)
        tangent = np.concatenate([t, zeros], axis=-1)
        normal = np.concatenate([-t[..., 1:2], t[..., 0:1], zeros], axis=-1)
        return origin, tangent, normal

    def _g(self, xy: np.ndarray, s: np.ndarray) -> np.ndarray:
        return np.asarray(np.sum((xy - self.point_xy(s)) * self.tangent_xy(s), axis=-1))

    def _point_one(self, s_mm: float) -> tuple[float, float]:
        """:meth:`point_xy` at one arc position, on Python floats (the same IEEE operations)."""
        cum = self._cum_list
        s = min(max(s_mm, 0.0), cum[-1])
        seg = min(max(bisect.bisect_right(cum, s) - 1, 0), len(cum) - 2)
        f = (s - cum[seg]) / (cum[seg + 1] - cum[seg])
        (x0, y0), (x1, y1) = self._xy_list[seg], self._xy_list[seg + 1]
        return x0 + f * (x1 - x0), y0 + f * (y1 - y0)

    def _tangent_one(self, s_mm: float) -> tuple[float, float]:
        """:meth:`tangent_xy` at one arc position, on Python floats (the same IEEE
        operations)."""
        half = 0.5 * self.window_mm
        if half == 0.0:
            cum = self._cum_list
            seg = min(max(bisect.bisect_right(cum, s_mm) - 1, 0), len(cum) - 2)
            (x0, y0), (x1, y1) = self._xy_list[seg], self._xy_list[seg + 1]
            cx, cy = x1 - x0, y1 - y0
        else:
            (px, py), (qx, qy) = self._point_one(s_mm + half), self._point_one(s_mm - half)
            cx, cy = px - qx, py - qy
        norm = math.sqrt(cx * cx + cy * cy)
        return cx / norm, cy / norm

    def _g_one(self, x: float, y: float, s_mm: float) -> float:
        """:meth:`_g` of one point at one arc position, on Python floats."""
        tx, ty = self._tangent_one(s_mm)
        px, py = self._point_one(s_mm)
        return (x - px) * tx + (y - py) * ty

    def _bisect_one(
        self, xy: np.ndarray, a: float, b: float, ga: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The bisection of :meth:`project` for one point, on Python floats: ``(a, b)``
        (compiled, the same operations, when its kernel is ready)."""
        from ctdrill.imaging.sampling.arch_kernel import ARCH_KERNEL  # numba: imported late

        x, y = float(xy[0]), float(xy[1])
        if ARCH_KERNEL.ready():
            out = np.empty(2)
            ARCH_KERNEL(
                self._cum, self._xy, 0.5 * self.window_mm, x, y, a, b, ga, _BISECT_STEPS, out
            )
            return out[:1], out[1:]
        for _ in range(_BISECT_STEPS):
            m = 0.5 * (a + b)
            gm = self._g_one(x, y, m)
            if (ga <= 0.0) == (gm <= 0.0):
                a, ga = m, gm
            else:
                b = m
        return np.array([a]), np.array([b])

    @functools.cached_property
    def _root_grid(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The grid on which :meth:`project` brackets roots: positions, points, tangents,
        normals (the curve's own: computed once)."""
        grid = self.grid_mm(min(_ROOT_GRID_MM, self.length_mm / 8.0))
        g_pts = self.point_xy(grid)
        g_tan = self.tangent_xy(grid)
        g_nrm = np.stack([-g_tan[:, 1], g_tan[:, 0]], axis=1)
        for arr in (grid, g_pts, g_tan, g_nrm):
            arr.flags.writeable = False
        return grid, g_pts, g_tan, g_nrm

    @functools.cached_property
    def _centroid_xy(self) -> np.ndarray:
        """(2,) the centroid of the curve's points every 1 mm of arc (lingual of a curved
        arch)."""
        out = np.asarray(np.mean(self.point_xy(self.grid_mm(1.0)), axis=0))
        out.flags.writeable = False
        return out

    def project(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Arc position and signed normal offset of LPS points on the curtain.

        Parameters
        ----------
        points_lps : np.ndarray
            (N, 3) LPS mm.

        Returns
        -------
        s_mm, offset_mm : np.ndarray
            (N,) arc position (mm from the arch's first point) and offset along the normal
            (mm); NaN where the point's normal foot lies beyond the arch's ends.
        """
        pts = np.asarray(points_lps, dtype=np.float64).reshape(-1, 3)
        s_out = np.full(len(pts), np.nan)
        t_out = np.full(len(pts), np.nan)
        grid, g_pts, g_tan, g_nrm = self._root_grid
        for start in range(0, len(pts), _PROJECT_CHUNK):
            xy = pts[start : start + _PROJECT_CHUNK, :2]
            d = xy[:, None, :] - g_pts[None, :, :]
            g = np.sum(d * g_tan[None], axis=2)  # (n, M)
            g[np.abs(g) < _ZERO_MM] = 0.0  # on a grid column up to rounding (the ends too)
            off = np.sum(d * g_nrm[None], axis=2)
            lo_g, hi_g = g[:, :-1], g[:, 1:]
            bracket = ((lo_g <= 0.0) & (hi_g >= 0.0)) | ((lo_g >= 0.0) & (hi_g <= 0.0))
            if not bracket.any():
                continue
            # Approximate offset at each bracket: pick the root nearest the curtain.
            score = np.where(bracket, np.abs(0.5 * (off[:, :-1] + off[:, 1:])), np.inf)
            k = np.argmin(score, axis=1)
            found = np.isfinite(score[np.arange(len(k)), k])
            rows = np.nonzero(found)[0]
            a = grid[k[rows]]
            b = grid[k[rows] + 1]
            sub = xy[rows]
            ga0 = _snap(self._g(sub, a))
            gb0 = _snap(self._g(sub, b))
            a0, b0, ga = a.copy(), b.copy(), ga0
            if len(rows) == 1:  # one point (an implant's site): the same steps on floats
                a, b = self._bisect_one(sub[0], float(a[0]), float(b[0]), float(ga[0]))
            for _ in range(_BISECT_STEPS if len(rows) > 1 else 0):
                m = 0.5 * (a + b)
                gm = self._g(sub, m)
                left = (ga <= 0.0) == (gm <= 0.0)
                a = np.where(left, m, a)
                ga = np.where(left, gm, ga)
                b = np.where(left, b, m)
            s = np.where(ga0 == 0.0, a0, np.where(gb0 == 0.0, b0, 0.5 * (a + b)))
            _, _, nrm = self.frame(s)
            org = self.point_xy(s)
            s_out[start + rows] = s
            t_out[start + rows] = np.sum((sub - org) * nrm[:, :2], axis=1)
        return s_out, t_out

    def arc_of_one(self, x: float, y: float) -> float | None:
        """:meth:`project`'s arc position of the one point ``(x, y)`` (the same operations,
        without the arrays' overhead); None where its normal foot lies beyond the ends."""
        grid, g_pts, g_tan, g_nrm = self._root_grid
        d = np.array([x, y]) - g_pts
        g = np.sum(d * g_tan, axis=1)
        g[np.abs(g) < _ZERO_MM] = 0.0
        off = np.sum(d * g_nrm, axis=1)
        lo_g, hi_g = g[:-1], g[1:]
        bracket = ((lo_g <= 0.0) & (hi_g >= 0.0)) | ((lo_g >= 0.0) & (hi_g <= 0.0))
        score = np.where(bracket, np.abs(0.5 * (off[:-1] + off[1:])), np.inf)
        k = int(np.argmin(score))
        if not np.isfinite(score[k]):
            return None
        a, b = float(grid[k]), float(grid[k + 1])
        ga0 = self._g_one(x, y, a)
        ga0 = 0.0 if abs(ga0) < _ZERO_MM else ga0
        gb0 = self._g_one(x, y, b)
        if ga0 == 0.0:
            return a
        if abs(gb0) < _ZERO_MM:
            return b
        lo, hi = self._bisect_one(np.array([x, y]), a, b, ga0)
        return float(0.5 * (lo[0] + hi[0]))

    def buccal_normal_xy(self, s_mm: float) -> np.ndarray | None:
        """(2,) the unit normal at arc ``s_mm`` that points to the **buccal** side: away from
        the centroid of the arch (which lies on the concave, lingual side of any curved arch
        or arc of one); None where the arch is straight (its centroid on the normal line)."""
        tx, ty = self._tangent_one(s_mm)
        normal = np.array([-ty, tx])  # frame()'s normal, ez x tangent
        inward = float((self._centroid_xy - np.array(self._point_one(s_mm))) @ normal)
        if abs(inward) < STRAIGHT_MM:
            return None
        out: np.ndarray = -normal if inward > 0.0 else normal
        return out

    def min_radius_mm(self, step_mm: float = _ROOT_GRID_MM) -> float:
        """Smallest radius of curvature of the smoothed normals (mm): slab half-thicknesses
        beyond it fold (inf for a straight arch)."""
        grid = self.grid_mm(step_mm)
        t = self.tangent_xy(grid)
        ang = np.unwrap(np.arctan2(t[:, 1], t[:, 0]))
        rate = np.abs(np.diff(ang)) / np.diff(grid)
        peak = float(np.max(rate)) if rate.size else 0.0
        return float("inf") if peak <= 1e-12 else 1.0 / peak


def _snap(g: np.ndarray) -> np.ndarray:
    return np.where(np.abs(g) < _ZERO_MM, 0.0, g)


def arc_position_mm(
    arch_lps: np.ndarray, point_lps: np.ndarray, *, window_mm: float = TANGENT_WINDOW_MM
) -> float:
    """Arc position (mm from the arch's first point) of the panorama column through a point.

    The point projects along the smoothed bucco-lingual normals (the panorama's own geometry,
    see the module docstring), so the panorama column at this position passes through it.

    Raises
    ------
    ArchInputError
        The point's normal foot lies beyond the arch's ends.
    """
    curve = ArchCurve(np.asarray(arch_lps), window_mm)
    pt = np.asarray(point_lps, dtype=np.float64).reshape(1, 3)
    s, _ = curve.project(pt)
    if not np.isfinite(s[0]):
        raise ArchInputError(
            f"arch: the point {np.round(pt[0], 2).tolist()} (LPS mm) lies beyond the arch's "
            "ends; extend the arch past the implant site"
        )
    return float(s[0])


def arch_curve(arch_lps: np.ndarray, window_mm: float = TANGENT_WINDOW_MM) -> ArchCurve:
    """The :class:`ArchCurve` of ``arch_lps``, built once per arch (a plan's arch is read for
    every implant placed on it: ``suggest`` checks many axes of one plan)."""
    arch = np.ascontiguousarray(arch_lps, dtype=np.float64)
    return _cached_curve(arch.tobytes(), arch.shape, float(window_mm))


@functools.lru_cache(maxsize=32)
def _cached_curve(data: bytes, shape: tuple[int, ...], window_mm: float) -> ArchCurve:
    return ArchCurve(np.frombuffer(data, dtype=np.float64).reshape(shape), window_mm)


def buccal_normal_lps(
    arch_lps: np.ndarray, point_lps: np.ndarray, *, window_mm: float = TANGENT_WINDOW_MM
) -> np.ndarray | None:
    """(3,) horizontal unit vector to the buccal side of the arch at the panorama column
    through ``point_lps`` (:meth:`ArchCurve.buccal_normal_xy`); None when the point lies
    beyond the arch's ends or the arch is straight there."""
    curve = arch_curve(arch_lps, window_mm)
    point = np.asarray(point_lps, dtype=np.float64).reshape(3)
    s = curve.arc_of_one(float(point[0]), float(point[1]))
    if s is None or not math.isfinite(s):
        return None
    xy = curve.buccal_normal_xy(s)
    return None if xy is None else np.array([xy[0], xy[1], 0.0])
