"""What the plan puts on a reformat, in image millimetres: canal zones, bodies, captions.

Headless (numpy and scipy only), so the drawing (:mod:`ctdrill.app.reformat.draw`) only draws.
Image coordinates are those of :meth:`Reformat.project`: ``(u, v)`` mm from the top-left pixel
centre, ``u`` along the columns and ``v`` down the rows.

- **Tubes** (a canal: centre line + radius, its margin zone around it). Each pixel gets the
  distance from its slab (the segment through the pixel across the slab) to the centre line,
  measured in image coordinates: the centre line is resampled every ``_TUBE_STEP_MM`` (at most),
  each sample ``q`` projected to ``(u_q, v_q)`` with slab offset ``t_q``, and
  ``d = min_q |(u, v, 0) - (u_q, v_q, max(0, |t_q| - slab / 2))|`` (a k-d tree). The tube is
  ``d <= radius``, the margin zone ``radius < d <= radius + margin``: exactly the set of pixels
  whose slab meets the tube (or the zone) on a cross-section; on a panorama, within the
  stretch of the curved frame (a few % at 1 mm from a 25 mm radius arch). The resampling
  changes distances by at most ``step^2 / (8 d)`` (0.001 mm at 0.1 mm steps, 1.2 mm away).
- **Bodies** (implant, drill): solids of revolution about an axis, outlined by their silhouette
  in the image: the profile ``r(s)`` laid out on both sides of the axis along the image's own
  column direction made perpendicular to the axis.
- **Captions**: whatever lies outside the slab, or beyond the arch's ends, is said, not hidden.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass

import numpy as np

from ctdrill.imaging.sampling.reformat import Reformat

#: Largest step (mm) between resampled centre-line points.
_TUBE_STEP_MM = 0.1
#: Most resampled points of one centre line (the step grows beyond).
_MAX_TUBE_POINTS = 40_000


@dataclass(frozen=True, eq=False)
class TubeOverlay:
    """A canal (tube) on a reformat.

    Attributes
    ----------
    name : str
        The landmark's name.
    radius_mm, margin_mm : float
        Tube radius and margin zone width, mm.
    distance_mm : np.ndarray
        (H, W) distance from each pixel's slab to the centre line, mm (inf from two pixels
        beyond the margin zone's reach).
    centre_runs_uv : tuple[np.ndarray, ...]
        Runs (M, 2) of the centre line where it lies inside the slab, image mm.
    gap_mm : float | None
        How far the margin zone stays from the slab (0 when it reaches it); None when the
        centre line does not project onto the image at all (beyond the arch's ends).
    """

    name: str
    radius_mm: float
    margin_mm: float
    distance_mm: np.ndarray
    centre_runs_uv: tuple[np.ndarray, ...]
    gap_mm: float | None

    @property
    def visible(self) -> bool:
        """True when the tube or its margin zone reaches some pixel's slab."""
        return bool(np.any(self.distance_mm <= self.radius_mm + max(self.margin_mm, 0.0)))

    def caption(self) -> str | None:
        """What to say when the zone is not on the image (None when it is)."""
        if self.visible:
            return None
        if self.gap_mm is None:
            return f"{self.name}: beyond the arch's ends, not on this view"
        return f"{self.name}: {self.gap_mm:.1f} mm outside the slab (margin zone), not drawn"


def resample_polyline(points_lps: np.ndarray, step_mm: float) -> np.ndarray:
    """(M, 3) the polyline with points at most ``step_mm`` apart, its vertices kept."""
    pts = np.asarray(points_lps, dtype=np.float64).reshape(-1, 3)
    if len(pts) < 2:
        return pts
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    step = max(step_mm, float(seg.sum()) / _MAX_TUBE_POINTS)
    out = [pts[:1]]
    for a, b, length in zip(pts[:-1], pts[1:], seg, strict=True):
        n = max(1, int(np.ceil(length / step)))
        f = np.arange(1, n + 1, dtype=np.float64) / n
        out.append(a + f[:, None] * (b - a))
    return np.concatenate(out)


def _runs(mask: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, ...]:
    """Consecutive stretches of ``uv`` where ``mask`` holds (at least two points each)."""
    runs: list[np.ndarray] = []
    start = None
    for k, ok in enumerate(np.append(mask, False)):
        if ok and start is None:
            start = k
        elif not ok and start is not None:
            if k - start >= 2:
                runs.append(uv[start:k])
            start = None
    return tuple(runs)


#: Tube overlays kept per reformat (the same canal drawn again on the same image: the report's
#: implant pages share the case's panorama; a window redraw). They die with the reformat.
_TUBES: weakref.WeakKeyDictionary[Reformat, dict[tuple[object, ...], TubeOverlay]] = (
    weakref.WeakKeyDictionary()
)
_TUBES_LOCK = threading.Lock()
#: Most tube overlays kept for one reformat.
_TUBES_PER_REFORMAT = 8


def tube_overlay(
    reformat: Reformat, polyline_lps: np.ndarray, radius_mm: float, margin_mm: float, name: str
) -> TubeOverlay:
    """The canal's tube and margin zone on the reformat (module docstring); the same
    arguments on the same reformat give the overlay already computed (its arrays read-only)."""
    line = np.ascontiguousarray(polyline_lps, dtype=np.float64)
    key = (line.shape, line.tobytes(), float(radius_mm), float(margin_mm), name)
    with _TUBES_LOCK:
        kept = _TUBES.get(reformat)
        if kept is not None and key in kept:
            return kept[key]
    tube = _tube_overlay(reformat, line, radius_mm, margin_mm, name)
    with _TUBES_LOCK:
        kept = _TUBES.setdefault(reformat, {})
        if len(kept) >= _TUBES_PER_REFORMAT:
            kept.clear()
        kept[key] = tube
    return tube


def _tube_overlay(
    reformat: Reformat, polyline_lps: np.ndarray, radius_mm: float, margin_mm: float, name: str
) -> TubeOverlay:
    pts = resample_polyline(polyline_lps, min(_TUBE_STEP_MM, reformat.pixel_mm / 4.0))
    uv, off = reformat.project(pts)
    uv.flags.writeable = False  # the centre runs are views of it, kept with the overlay
    h, w = reformat.shape
    reach = float(radius_mm) + max(float(margin_mm), 0.0)
    dist = np.full((h, w), np.inf)
    ok = np.all(np.isfinite(uv), axis=1)
    if not ok.any():
        return TubeOverlay(name, float(radius_mm), float(margin_mm), dist, (), None)
    excess = np.maximum(np.abs(off) - 0.5 * reformat.slab_mm, 0.0)
    near = ok & (excess <= reach)
    gap = float(max(np.min(excess[ok]) - reach, 0.0))
    runs = _runs(ok & (excess == 0.0), uv)
    if near.any():
        from scipy.spatial import cKDTree  # here: its import costs start-up, few need it

        p = reformat.pixel_mm
        tree = cKDTree(np.column_stack([uv[near], excess[near]]))
        lo = np.floor((uv[near].min(axis=0) - reach) / p).astype(int) - 2
        hi = np.ceil((uv[near].max(axis=0) + reach) / p).astype(int) + 2
        j0, i0 = max(lo[0], 0), max(lo[1], 0)
        j1, i1 = min(hi[0], w - 1), min(hi[1], h - 1)
        if j0 <= j1 and i0 <= i1:
            jj, ii = np.meshgrid(np.arange(j0, j1 + 1), np.arange(i0, i1 + 1))
            q = np.column_stack([jj.ravel() * p, ii.ravel() * p, np.zeros(jj.size)])
            # Two pixels beyond the reach, so contours interpolate between finite values.
            d, _ = tree.query(q, distance_upper_bound=reach + 2.0 * p)
            dist[i0 : i1 + 1, j0 : j1 + 1] = np.asarray(d).reshape(jj.shape)
    dist.flags.writeable = False
    return TubeOverlay(name, float(radius_mm), float(margin_mm), dist, runs, gap)


@dataclass(frozen=True, eq=False)
class BodyOverlay:
    """A solid of revolution (implant, drill) on a reformat.

    Attributes
    ----------
    name : str
        What it is (for captions).
    outline_uv : np.ndarray
        (P, 2) closed silhouette polygon, image mm.
    axis_uv : np.ndarray
        (2, 2) its axis from base to end, image mm.
    gap_mm : float
        How far the body stays from the slab (0 when it reaches it), mm.
    """

    name: str
    outline_uv: np.ndarray
    axis_uv: np.ndarray
    gap_mm: float

    @property
    def visible(self) -> bool:
        """True when the body reaches the slab and projects onto the image."""
        return self.gap_mm == 0.0 and bool(np.all(np.isfinite(self.outline_uv)))

    def caption(self) -> str | None:
        """What to say when it is not drawn (None when it is)."""
        if self.visible:
            return None
        if not np.all(np.isfinite(self.outline_uv)):
            return f"{self.name}: beyond the arch's ends, not on this view"
        return f"{self.name}: {self.gap_mm:.1f} mm outside the slab, not drawn"


def body_overlay(
    reformat: Reformat,
    base_lps: np.ndarray,
    axis_lps: np.ndarray,
    s_mm: np.ndarray,
    r_mm: np.ndarray,
    name: str,
) -> BodyOverlay:
    """Silhouette of the solid ``r(s)`` about the axis from ``base_lps`` (module docstring)."""
    base = np.asarray(base_lps, dtype=np.float64).reshape(3)
    axis = np.asarray(axis_lps, dtype=np.float64).reshape(3)
    axis = axis / np.linalg.norm(axis)
    s = np.asarray(s_mm, dtype=np.float64).reshape(-1)
    r = np.asarray(r_mm, dtype=np.float64).reshape(-1)
    mid = base + 0.5 * (s[0] + s[-1]) * axis
    col, down, _slab = (v[0] for v in reformat.directions_lps(mid[None]))
    side = col - (col @ axis) * axis
    if not np.all(np.isfinite(side)) or np.linalg.norm(side) < 1e-6:
        side = down - (down @ axis) * axis  # axis along the columns: lay out along the rows
    if np.all(np.isfinite(side)):
        side = side / np.linalg.norm(side)
    core = base[None, :] + s[:, None] * axis[None, :]
    left = core + r[:, None] * side[None, :]
    right = core - r[:, None] * side[None, :]
    outline = np.concatenate([left, right[::-1], left[:1]])
    uv, _ = reformat.project(outline)
    axis_uv, axis_off = reformat.project(core[[0, -1]])
    # Distance of the axis segment from the slab: 0 when it crosses the slab's middle.
    if np.all(np.isfinite(axis_off)) and axis_off[0] * axis_off[1] <= 0.0:
        nearest = 0.0
    else:
        nearest = float(np.nanmin(np.abs(axis_off))) if np.any(np.isfinite(axis_off)) else 0.0
    gap = max(nearest - 0.5 * reformat.slab_mm - float(np.max(r)), 0.0)
    return BodyOverlay(name, uv, axis_uv, gap)


def drill_profile_mm(
    stop_depth_mm: float, diameter_mm: float, tip_length_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """(s, r) of the drill solid from the entry (s = 0) to its tip at ``stop_depth_mm``:
    a cylinder of the drill's radius, then the tip cone of ``tip_length_mm`` (DESIGN.md 2)."""
    radius = 0.5 * float(diameter_mm)
    depth = max(float(stop_depth_mm), 0.0)
    tip = max(float(tip_length_mm), 0.0)
    if tip <= 0.0:
        return np.array([0.0, depth, depth]), np.array([radius, radius, 0.0])
    if depth <= tip:
        return np.array([0.0, depth]), np.array([radius * depth / tip, 0.0])
    return np.array([0.0, depth - tip, depth]), np.array([radius, radius, 0.0])
