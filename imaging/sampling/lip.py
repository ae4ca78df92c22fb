"""Samples of the CT on the drill's conical cutting lip (DESIGN.md 1.4).

The lip runs from the tip point (radius 0, depth ``x``) to the outer corner (radius ``R`` =
diameter / 2, depth ``x - l_t``), ``l_t`` the tip length. Its radial extent is cut into
``n_rings`` equal bins; ring ``i`` sits at the bin midpoint ``r_i = (i + 1/2) R / n_rings``, at
depth ``xi_i = x - l_t r_i / R`` along the drill axis, and is sampled at ``n_angles`` equally
spaced angles around the axis. The midpoint rule gives each ring the weight ``1 / n_rings`` in
``(1/R) integral_0^R ... dr``.

Depth is measured from the entry point along the unit axis ``(target - entry) / |target - entry|``;
all points are LPS millimetres.

Defaults (``n_rings=6``, ``n_angles=12``) come from ``bench/bench_sampling.py`` (docs/benchmarks.md,
"Lip sampling"): on 0.3 mm voxels with trilinear interpolation and a 0.05 mm depth step they
keep the discretisation error of ``s_t`` at 0.004 RMS and of the lip-mean HU under 1 HU, some
20 times below the partial-volume error of the CT itself, for ~3 ms per 16 mm trajectory;
coarser lips (3 x 8, 2 x 6) are 3-7 times less accurate, finer ones cost 3-16 times more.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.annulus import Hole, annulus_rings
from ctdrill.imaging.volume import CTVolume

#: Default number of rings on the lip (measured, bench/bench_sampling.py).
DEFAULT_N_RINGS = 6
#: Default number of angles per ring (measured, bench/bench_sampling.py).
DEFAULT_N_ANGLES = 12


class LipInputError(ImagingInputError):
    """Bad trajectory or drill geometry given to the lip sampler."""


@dataclass(frozen=True, eq=False)
class LipSamples:
    """HU on the cutting lip at each tip depth.

    Attributes
    ----------
    depth_mm : np.ndarray
        (D,) tip depth along the axis from the entry point, mm.
    radii_mm : np.ndarray
        (R,) ring radii, mm (midpoints of equal radial bins); (D, R) per depth for a drill
        following narrower ones (rings on the lip outside their holes).
    ring_weights : np.ndarray
        (R,) quadrature weights of ``(1/R) integral dr``: each ``1 / R``, they sum to 1;
        (D, R) with the radii: each depth's weights sum to the cut share ``|C(x)| / R``.
    hu : np.ndarray
        (D, R, A) float32 HU at ring point (radius r, angle a), at depth ``x - l_t r / R``.
    outside : np.ndarray
        (D,) int64: ring samples outside the volume or touching padding, per depth.
    axis_hu : np.ndarray
        (D,) float64 HU on the axis at the tip point.
    """

    depth_mm: np.ndarray
    radii_mm: np.ndarray
    ring_weights: np.ndarray
    hu: np.ndarray
    outside: np.ndarray
    axis_hu: np.ndarray

    @property
    def lip_mean_hu(self) -> np.ndarray:
        """(D,) lip-mean HU: ring means over angles, weighted by ``ring_weights`` (per-depth
        weights are normalised: the mean over the part of the lip that cuts)."""
        ring_mean = self.hu.mean(axis=2, dtype=np.float64)
        if self.ring_weights.ndim == 1:
            return np.asarray(ring_mean @ self.ring_weights)
        w = self.ring_weights
        return np.asarray((ring_mean * w).sum(axis=1) / w.sum(axis=1))


def axis_basis(entry_lps: np.ndarray, target_lps: np.ndarray) -> np.ndarray:
    """Orthonormal right-handed frame of the drill axis.

    Parameters
    ----------
    entry_lps, target_lps : np.ndarray
        (3,) LPS mm; they must differ.

    Returns
    -------
    np.ndarray
        (3, 3) rows ``(axis, e1, e2)``: ``axis`` the unit vector entry -> target, ``e1`` the
        coordinate axis least aligned with it (first one on ties) made orthogonal and
        normalised, ``e2 = axis x e1``. Deterministic for a given axis.
    """
    entry = _point(entry_lps, "entry_lps")
    target = _point(target_lps, "target_lps")
    d = target - entry
    norm = float(np.linalg.norm(d))
    if not norm > 1e-9:
        raise LipInputError(
            "trajectory: entry and target are the same point; plan a target away from the entry"
        )
    axis = d / norm
    helper = np.zeros(3)
    helper[int(np.argmin(np.abs(axis)))] = 1.0
    e1 = helper - float(helper @ axis) * axis
    e1 /= np.linalg.norm(e1)
    # axis x e1, written out: np.cross costs more than the rest of this function.
    e2 = np.array(
        [
            axis[1] * e1[2] - axis[2] * e1[1],
            axis[2] * e1[0] - axis[0] * e1[2],
            axis[0] * e1[1] - axis[1] * e1[0],
        ]
    )
    return np.stack([axis, e1, e2])


def ring_radii_mm(diameter_mm: float, n_rings: int) -> np.ndarray:
    """(n_rings,) midpoints of ``n_rings`` equal radial bins on ``[0, diameter / 2]``, mm."""
    radius = _positive(diameter_mm, "drill.diameter_mm") / 2.0
    n = _count(n_rings, "n_rings")
    return (np.arange(n, dtype=np.float64) + 0.5) * (radius / n)


def lip_ring_points(
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    depth_mm: np.ndarray,
    drill: DrillSpec,
    *,
    n_rings: int = DEFAULT_N_RINGS,
    n_angles: int = DEFAULT_N_ANGLES,
    holes: Sequence[Hole] = (),
) -> np.ndarray:
    """LPS positions of the lip's ring samples.

    Parameters
    ----------
    entry_lps, target_lps : np.ndarray
        (3,) LPS mm; depth 0 is the entry, the axis points to the target.
    depth_mm : np.ndarray
        (D,) tip depths, mm (any finite values).
    drill : DrillSpec
        ``diameter_mm`` (> 0) and ``tip_length_mm``, the axial length of the conical tip
        (>= 0; 0 is a flat lip).
    n_rings, n_angles : int
        Rings on the lip and samples per ring (>= 1).
    holes : Sequence[Hole]
        Holes of earlier drills of a sequence: the rings then lie on the part of the lip
        outside them (:mod:`ctdrill.imaging.sampling.annulus`), their radii per depth.

    Returns
    -------
    np.ndarray
        (D, n_rings, n_angles, 3) LPS mm. Point ``[d, i, a]`` lies at distance ``r_i`` from the
        axis, at depth ``depth_mm[d] - tip_length_mm * r_i / R`` along it, at angle
        ``2 pi a / n_angles`` from ``e1`` towards ``e2`` (:func:`axis_basis`).
    """
    return _ring_points(entry_lps, target_lps, depth_mm, drill, n_rings, n_angles, holes)[0]


def _ring_points(
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    depth_mm: np.ndarray,
    drill: DrillSpec,
    n_rings: int,
    n_angles: int,
    holes: Sequence[Hole] = (),
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`lip_ring_points`, plus the unit axis (3,), the ring radii in mm and the ring
    weights: (R,) each for the full lip, (D, R) each on the cut set when ``holes`` are given
    (:func:`ctdrill.imaging.sampling.annulus.annulus_rings`)."""
    depth = _depths(depth_mm)
    tip_len = float(drill.tip_length_mm)
    if not (np.isfinite(tip_len) and tip_len >= 0.0):
        raise LipInputError(
            f"drill.tip_length_mm: must be a finite length >= 0 mm, got {drill.tip_length_mm!r}"
        )
    radii = ring_radii_mm(drill.diameter_mm, n_rings)
    weights = np.full(radii.size, 1.0 / radii.size)
    n_a = _count(n_angles, "n_angles")
    axis, e1, e2 = axis_basis(entry_lps, target_lps)
    entry = np.asarray(entry_lps, dtype=np.float64)
    radius = float(drill.diameter_mm) / 2.0
    theta = 2.0 * np.pi * np.arange(n_a, dtype=np.float64) / n_a
    ring_unit = np.cos(theta)[:, None] * e1 + np.sin(theta)[:, None] * e2  # (A, 3)
    points = np.empty((depth.size, radii.size, n_a, 3))
    if holes:
        radii, weights = annulus_rings(radius, tip_len, depth, holes, radii.size)  # (D, R)
        xi = depth[:, None] - tip_len * radii / radius
        centres = entry + xi[:, :, None] * axis  # (D, R, 3)
        for c in range(3):
            np.add(
                centres[:, :, None, c],
                radii[:, :, None] * ring_unit[None, None, :, c],
                out=points[..., c],
            )
        return points, axis, radii, weights
    xi = depth[:, None] - tip_len * radii[None, :] / radius  # (D, R)
    offsets = radii[:, None, None] * ring_unit[None, :, :]  # (R, A, 3)
    centres = entry + xi[:, :, None] * axis  # (D, R, 3)
    # One coordinate at a time: a broadcast add with a trailing axis of 3 is ~4x slower.
    for c in range(3):
        np.add(centres[:, :, None, c], offsets[None, :, :, c], out=points[..., c])
    return points, axis, radii, weights


def sample_lip_rings(
    volume: CTVolume,
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    depth_mm: np.ndarray,
    drill: DrillSpec,
    *,
    n_rings: int = DEFAULT_N_RINGS,
    n_angles: int = DEFAULT_N_ANGLES,
    outside_hu: float = AIR_HU,
    order: int = 1,
    holes: Sequence[Hole] = (),
) -> LipSamples:
    """HU on the cutting lip at each tip depth, in one vectorised volume lookup.

    Parameters
    ----------
    volume : CTVolume
        The CT.
    entry_lps, target_lps : np.ndarray
        (3,) LPS mm.
    depth_mm : np.ndarray
        (D,) tip depths from the entry along the axis, mm.
    drill : DrillSpec
        Drill geometry (``diameter_mm``, ``tip_length_mm``).
    n_rings, n_angles : int
        Lip discretisation (defaults measured in bench/bench_sampling.py).
    outside_hu : float
        HU given to samples outside the volume or on padding (also counted in ``outside``).
    order : int
        Interpolation order passed to :meth:`CTVolume.sample` (1 trilinear, 0 nearest).
    holes : Sequence[Hole]
        Holes left by earlier drills of a sequence (:mod:`ctdrill.imaging.sampling.annulus`):
        the rings are placed on the lip outside them, radii and weights per depth.

    Returns
    -------
    LipSamples
        ``hu`` (D, n_rings, n_angles) float32, ``axis_hu`` (D,), ``outside`` (D,) counts.
    """
    points, axis, radii, weights = _ring_points(
        entry_lps, target_lps, depth_mm, drill, n_rings, n_angles, holes
    )
    depth = _depths(depth_mm)
    if not np.isfinite(outside_hu):
        raise LipInputError(f"outside_hu: must be a finite HU value, got {outside_hu!r}")
    tips = np.asarray(entry_lps, dtype=np.float64) + depth[:, None] * axis  # (D, 3)
    n_d, n_r, n_a = points.shape[:3]
    flat = points.reshape(-1, 3)
    everything = np.concatenate([flat, tips])
    # One lookup with NaN as the outside value marks every sample outside the grid or touching
    # padding (NaN propagates through the interpolation weights). Only those few samples are
    # looked up again, for their exact value with ``outside_hu`` and the exact inside test.
    values = volume.sample(everything, order=order, outside_hu=np.nan)
    flagged = np.flatnonzero(np.isnan(values))
    outside_flat = np.zeros(everything.shape[0], dtype=bool)
    if flagged.size:
        values[flagged] = volume.sample(
            everything[flagged], order=order, outside_hu=float(outside_hu)
        )
        outside_flat[flagged] = ~volume.inside(everything[flagged])
    n_ring = flat.shape[0]
    ring_hu = values[:n_ring].reshape(n_d, n_r, n_a).astype(np.float32)
    outside = outside_flat[:n_ring].reshape(n_d, n_r * n_a).sum(axis=1).astype(np.int64)
    return LipSamples(
        depth_mm=depth,
        radii_mm=radii,
        ring_weights=weights,
        hu=ring_hu,
        outside=outside,
        axis_hu=np.asarray(values[n_ring:], dtype=np.float64),
    )


def _point(value: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise LipInputError(f"{name}: expected 3 finite LPS coordinates in mm, got {value!r}")
    return arr


def _depths(depth_mm: np.ndarray) -> np.ndarray:
    depth = np.asarray(depth_mm, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(depth)):
        raise LipInputError("depth_mm: every tip depth must be finite (mm)")
    return depth


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 0.0):
        raise LipInputError(f"{name}: must be a finite length > 0 mm, got {value!r}")
    return v


def _count(value: int, name: str) -> int:
    n = int(value)
    if n < 1 or n != value:
        raise LipInputError(f"{name}: must be a whole number >= 1, got {value!r}")
    return n
