"""Clearances of many drill axes at once, as arrays (the batched ``clearance_profile_mm``).

For ``N`` drill axes sharing one drill and one set of landmarks, :class:`ClearanceField` gives
the signed clearance from the drill solid to every landmark at any depths of each row: with
the compiled kernel of :mod:`ctdrill.imaging.plan.clearance_kernel` when its cache is present
and every landmark kind is known to it, else with each landmark's own ``clearance_mm`` row by
row (the NumPy path; the same arrays, tests hold the two equal). It computes arrays only: the
safe-depth rule that reads them is :func:`~ctdrill.imaging.plan.safety.search_safe_depths`.
Every landmark is handed to the kernel as segments (a canal's centreline and radius, a point,
a mask's :func:`~ctdrill.imaging.plan.voxels.voxel_union_segments` for each axis), as the
landmark's own ``clearance_mm`` measures it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.imaging.plan.clearance_kernel import CLEARANCE_KERNEL
from ctdrill.imaging.plan.distance import DrillSolid
from ctdrill.imaging.plan.landmarks import CanalLandmark, Landmark, MaskLandmark, PointLandmark
from ctdrill.imaging.plan.voxels import voxel_union_segments
from ctdrill.jit import row_spans, run_spans


def landmark_segments(
    landmark: Landmark, solid: DrillSolid
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """``(a, b, radius)``: the segments whose nearest point to the solid gives the landmark's
    clearance (minus ``radius``), as its own ``clearance_mm`` measures them; None for a kind
    the kernel does not know (then the NumPy path runs)."""
    if isinstance(landmark, CanalLandmark):
        a, b = landmark.segments_lps()
        return a, b, float(landmark.radius_mm)
    if isinstance(landmark, PointLandmark):
        pt = landmark.point_lps[None, :]
        return pt, pt, 0.0
    if isinstance(landmark, MaskLandmark) and landmark.affine_lps is not None:
        a, b = voxel_union_segments(landmark.mask, landmark.affine_lps, solid)
        return a, b, 0.0
    return None


def unit_directions(entries_lps: np.ndarray, targets_lps: np.ndarray) -> np.ndarray:
    """(N, 3) each axis's unit vector, as :attr:`Plan.direction` and then :class:`DrillSolid`
    normalise it."""
    d = targets_lps - entries_lps
    with np.errstate(invalid="ignore", divide="ignore"):
        u = d / np.sqrt(np.sum(d * d, axis=1))[:, None]
        return np.asarray(u / np.sqrt(np.sum(u * u, axis=1))[:, None])


@dataclass(frozen=True, eq=False)
class _Segments:
    """The kernel's input: every landmark's segments (shared, or per row for masks)."""

    seg_a: np.ndarray
    seg_b: np.ndarray
    ptr: np.ndarray  # (N, L, 2) each row's span of each landmark's segments
    radii_l: np.ndarray  # (L,)


@dataclass(frozen=True, eq=False)
class ClearanceField:
    """Clearance of ``N`` axes (one drill) to the landmarks, at any depths.

    Attributes
    ----------
    landmarks : (L,) landmarks bound to the CT grid.
    radius_mm, tip_length_mm : the drill.
    entries_lps : (N, 3) LPS mm.
    directions : (N, 3) unit axes.
    segments : the compiled kernel's input, or None (the NumPy path).
    """

    landmarks: tuple[Landmark, ...]
    radius_mm: float
    tip_length_mm: float
    entries_lps: np.ndarray
    directions: np.ndarray
    segments: _Segments | None

    @classmethod
    def prepare(
        cls,
        landmarks: tuple[Landmark, ...],
        radius_mm: float,
        tip_length_mm: float,
        entries_lps: np.ndarray,
        targets_lps: np.ndarray,
        rows: np.ndarray,
    ) -> ClearanceField:
        """The field of ``rows`` (their axes must not be degenerate); the kernel's segments
        when it is ready and knows every landmark kind."""
        entries = np.ascontiguousarray(entries_lps, dtype=np.float64)
        todo = np.asarray(rows, dtype=np.int64)
        dirs = np.zeros_like(entries)
        dirs[todo] = unit_directions(entries[todo], np.asarray(targets_lps)[todo])
        segments = None
        if CLEARANCE_KERNEL.usable():  # compiled, or its own Python in a small job
            segments = _kernel_segments(landmarks, radius_mm, tip_length_mm, entries, dirs, todo)
        return cls(landmarks, float(radius_mm), float(tip_length_mm), entries, dirs, segments)

    @property
    def compiled(self) -> bool:
        """The compiled kernel computes this field."""
        return self.segments is not None

    def at(
        self,
        rows: np.ndarray,
        depth_mm: np.ndarray,
        n_depths: np.ndarray | None = None,
        *,
        stop_slack: tuple[np.ndarray, float] | None = None,
    ) -> np.ndarray:
        """(n, P, L) signed clearance of ``rows`` at ``depth_mm`` (n, P), mm; columns past a
        row's ``n_depths`` (default all P) are NaN. With ``stop_slack = (margins (L,), tol)``
        and ``depth_mm`` increasing along each row, the compiled kernel leaves NaN the columns
        after a row's first depth where ``clearance - margin - tol < 0`` for some landmark (a
        search for that depth reads no later one); the NumPy path computes them all."""
        rows = np.asarray(rows, dtype=np.int64)
        depth = np.ascontiguousarray(depth_mm, dtype=np.float64)
        n, p = rows.size, (depth.shape[1] if depth.ndim == 2 else 0)
        depth = depth.reshape(n, p)
        counts = (
            np.full(n, p, dtype=np.int64)
            if n_depths is None
            else np.ascontiguousarray(n_depths, dtype=np.int64)
        )
        out = np.full((n, p, len(self.landmarks)), np.nan)
        if n == 0 or not self.landmarks:
            return out
        seg = self.segments
        if seg is None:
            for j, i in enumerate(rows.tolist()):
                m = int(counts[j])
                solid = DrillSolid(
                    self.entries_lps[i], self.directions[i], self.radius_mm, self.tip_length_mm
                )
                for k, lm in enumerate(self.landmarks):
                    out[j, :m, k] = lm.clearance_mm(solid, depth[j, :m])
            return out
        if stop_slack is None:
            stop_margin, stop_tol = np.full(len(self.landmarks), -np.inf), 0.0
        else:
            stop_margin = np.ascontiguousarray(stop_slack[0], dtype=np.float64)
            stop_tol = float(stop_slack[1])
        run_spans(
            CLEARANCE_KERNEL,
            row_spans(np.arange(n)),
            seg.seg_a,
            seg.seg_b,
            np.ascontiguousarray(seg.ptr[rows]),
            seg.radii_l,
            np.ascontiguousarray(self.entries_lps[rows]),
            np.ascontiguousarray(self.directions[rows]),
            depth,
            counts,
            self.radius_mm,
            self.tip_length_mm,
            stop_margin,
            stop_tol,
            out,
        )
        return out


def _kernel_segments(
    landmarks: tuple[Landmark, ...],
    radius_mm: float,
    tip_length_mm: float,
    entries: np.ndarray,
    dirs: np.ndarray,
    todo: np.ndarray,
) -> _Segments | None:
    n_l = len(landmarks)
    starts: list[np.ndarray] = []
    ends: list[np.ndarray] = []
    radii_l = np.zeros(n_l)
    ptr = np.zeros((entries.shape[0], n_l, 2), dtype=np.int64)
    at = 0
    for lm_i, lm in enumerate(landmarks):
        shared = not isinstance(lm, MaskLandmark)
        for i in (todo[:1] if shared else todo).tolist():
            solid = DrillSolid(entries[i], dirs[i], radius_mm, tip_length_mm)
            seg = landmark_segments(lm, solid)
            if seg is None:
                return None
            a, b, radii_l[lm_i] = seg
            starts.append(np.asarray(a, dtype=np.float64).reshape(-1, 3))
            ends.append(np.asarray(b, dtype=np.float64).reshape(-1, 3))
            span = (at, at + len(starts[-1]))
            at = span[1]
            if shared:
                ptr[:, lm_i] = span
            else:
                ptr[i, lm_i] = span
    return _Segments(
        seg_a=np.ascontiguousarray(np.concatenate(starts) if starts else np.empty((0, 3))),
        seg_b=np.ascontiguousarray(np.concatenate(ends) if ends else np.empty((0, 3))),
        ptr=ptr,
        radii_l=radii_l,
    )
