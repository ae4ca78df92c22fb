"""What one drill path may ask of one CT volume: checks, gaps and the out-of-volume stop.

Exact or refused. The drill's cutting lip (DESIGN.md 1.4) is the cone segment from the tip
point (radius 0, depth ``x``) to the outer circle (radius ``R``, depth ``x - l_t``). Its data
are the CT's voxel-centre hull: in true index coordinates ``0 <= i, j, k <= n - 1``, which in
LPS is a parallelepiped (the slice index is piecewise linear in the normal position, so the
hull's two slice faces are the first and the last real slice planes). Everything below is in
closed form on that continuous lip, not on its ring samples:

- :func:`out_of_volume_depth_mm`: where the lip in contact first leaves the hull, under the
  entry rule (only the lip at or ahead of the entry must lie in the scan; an entry outside is
  refused with the part outside, the depths and the distance to move it):
  :mod:`ctdrill.imaging.sampling.edge` holds the closed form for any number of trajectories.
- :func:`crossed_gaps`: slice steps wider than ``stack.GAP_FACTOR`` nominal steps that the lip
  reaches into, with the depth range affected (the lip's slice-index range is linear in ``x``
  in the same way). Crossing one is refused unless the caller asks to interpolate across it.
- :func:`check_volume` / :func:`check_padding`: a single slice, values that are not HU and
  padding touched by the lip in contact (at or ahead of the entry, as for the volume edge)
  are refused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ctdrill.imaging.dicom.identity import series_label
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.annulus import Hole
from ctdrill.imaging.sampling.edge import (
    entry_refusal,
    face_terms,
    index_planes,
    lip_exit_depths,
    too_wide_refusal,
    whole_lip_fits,
)
from ctdrill.imaging.sampling.lip import LipSamples, axis_basis, lip_ring_points
from ctdrill.imaging.stack import GAP_FACTOR, nominal_step_mm, wide_steps
from ctdrill.imaging.volume import CTVolume


class PathInputError(ImagingInputError):
    """The volume cannot carry a force map safely along this drill path."""


@dataclass(frozen=True)
class SliceGap:
    """A slice step wider than ``GAP_FACTOR`` nominal steps that the drill lip reaches into.

    Attributes
    ----------
    lower_mm, upper_mm : float
        True positions along the slice normal of the two real slices around the gap, mm.
    nominal_step_mm : float
        The stack's nominal (median) step, mm.
    depth_from_mm, depth_to_mm : float
        Tip depths whose lip reaches into the gap, mm (within the depths checked).
    """

    lower_mm: float
    upper_mm: float
    nominal_step_mm: float
    depth_from_mm: float
    depth_to_mm: float

    @property
    def width_mm(self) -> float:
        """``|upper - lower|``, mm."""
        return abs(self.upper_mm - self.lower_mm)

    def describe(self) -> str:
        """One phrase naming the gap and the depths it affects."""
        return (
            f"a slice gap of {_mm(self.width_mm)} mm between the slices at "
            f"{_mm(self.lower_mm)} and {_mm(self.upper_mm)} mm along the slice normal "
            f"(nominal step {_mm(abs(self.nominal_step_mm))} mm; steps over {GAP_FACTOR:g} x "
            f"nominal are gaps) at tip depths {_mm(self.depth_from_mm)}.."
            f"{_mm(self.depth_to_mm)} mm"
        )


def _mm(value: float) -> str:
    """A length to the micrometre, without trailing zeros."""
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def check_volume(volume: CTVolume) -> None:
    """Refuse a volume that cannot carry a force map at all (one slice, values not HU)."""
    if not volume.is_volume:
        raise PathInputError(
            f"series {series_label(volume.info.series_uid)}: a single slice is not a volume; "
            "the force along a drill needs a CT series of several slices"
        )
    if not volume.info.is_hu:
        raise PathInputError(
            f"series {series_label(volume.info.series_uid)}: voxel values are not Hounsfield units "
            f"({_not_hu_cause(volume)}); map the grey values to HU before computing forces "
            "(--grey-to-hu SLOPE,INTERCEPT or --grey-ref regions)"
        )


def _not_hu_cause(volume: CTVolume) -> str:
    """Why the loader took the values for grey values: DICOM's RescaleType, or a file's range."""
    if volume.info.source_format == "DICOM":
        return f"RescaleType {volume.info.rescale_type or 'missing'}"
    return f"a {volume.info.source_format} file whose values look like grey values (not_hu)"


def require_grid_for_masks(
    volume: CTVolume, landmarks: tuple[Landmark, ...], *, name: str = ""
) -> None:
    """A mask landmark without its own grid takes the CT's: only a regular stack has one. A
    mask placed in a DICOM Frame of Reference (a SEG) must share the CT's (a DICOM series
    records its own; a file volume has none, and then nothing can be compared)."""
    ct_frame = volume.info.frame_of_reference_uid
    for lm in landmarks:
        frame = getattr(lm, "frame_of_reference_uid", None)
        if frame and ct_frame and frame != ct_frame:
            raise PathInputError(
                f"plan {name!r}: mask landmark {lm.name!r} ({getattr(lm, 'source', '') or 'SEG'}) "
                f"is placed in the Frame of Reference {frame}, the CT in {ct_frame}: the "
                "segmentation was made on another scan's coordinates, so where it lies in this "
                "CT is not known; segment this CT (or register the two and resample the SEG)"
            )
    needing = [lm for lm in landmarks if lm.needs_grid]
    if not needing or volume.regular:
        return
    for lm in needing:
        if lm.needs_grid:
            raise PathInputError(
                f"plan {name!r}: mask landmark {lm.name!r} has no affine_lps and the CT's "
                "slices are irregular (no single voxel grid); give the mask its own affine_lps "
                "or resample the series to uniform slices"
            )


def _lip_extremes(
    alpha: np.ndarray, entry_lps: np.ndarray, basis: np.ndarray, drill: DrillSpec
) -> tuple[float, float, float, float]:
    """For ``f(p) = alpha . p``: value at the entry, slope per mm of depth, and the lowest and
    highest offsets of the whole lip relative to its tip point."""
    axis, e1, e2 = basis
    su = float(alpha @ axis)
    w = math.hypot(float(alpha @ e1), float(alpha @ e2))
    lt, radius = float(drill.tip_length_mm), float(drill.radius_mm)
    low = min(0.0, -lt * su - radius * w)
    high = max(0.0, -lt * su + radius * w)
    return float(alpha @ entry_lps), su, low, high


def out_of_volume_depth_mm(
    volume: CTVolume,
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    drill: DrillSpec,
    planned_depth_mm: float,
    *,
    name: str = "",
) -> float | None:
    """Where the lip in contact first leaves the CT's voxel-centre hull (closed form; the
    entry rule of :mod:`ctdrill.imaging.sampling.edge`), for one trajectory.

    Returns
    -------
    float | None
        The depth where the lip's data end, mm; None when the lip stays inside down to
        ``planned_depth_mm``.

    Raises
    ------
    PathInputError
        The entry lies outside the scan (:func:`~ctdrill.imaging.sampling.edge.entry_refusal`).
    """
    entry = np.asarray(entry_lps, dtype=np.float64)
    target = np.asarray(target_lps, dtype=np.float64)
    terms = face_terms(volume, entry[None], target[None], drill)
    inside, exit_mm = lip_exit_depths(terms)
    if not inside[0]:
        raise PathInputError(entry_refusal(volume, entry, target, drill, name=name))
    if not whole_lip_fits(terms)[0]:
        raise PathInputError(too_wide_refusal(volume, drill, name=name))
    return None if exit_mm[0] >= planned_depth_mm else float(exit_mm[0])


def crossed_gaps(
    volume: CTVolume,
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    drill: DrillSpec,
    depth_end_mm: float,
) -> tuple[SliceGap, ...]:
    """Slice gaps (steps wider than ``GAP_FACTOR`` nominal steps) the lip reaches into for tip
    depths in ``[0, depth_end_mm]``, with the depths affected (closed form)."""
    wide = np.flatnonzero(wide_steps(volume.slice_positions_mm))
    if wide.size == 0:
        return ()
    lin, off, _ = index_planes(volume)
    k_aff = volume.affine_slice_index
    value, su, low, high = _lip_extremes(
        lin[2], np.asarray(entry_lps, dtype=np.float64), axis_basis(entry_lps, target_lps), drill
    )
    base = value + off[2]
    pos = volume.slice_positions_mm
    step = nominal_step_mm(pos)
    gaps: list[SliceGap] = []
    for k in wide:
        k_lo, k_hi = float(k_aff[k]), float(k_aff[k + 1])
        # lip range at depth x: [base + x su + low, base + x su + high]; open gap (k_lo, k_hi)
        if abs(su) < 1e-15:
            hit = base + high > k_lo and base + low < k_hi
            x1, x2 = (-math.inf, math.inf) if hit else (math.inf, -math.inf)
        else:
            t1, t2 = (k_lo - base - high) / su, (k_hi - base - low) / su
            x1, x2 = min(t1, t2), max(t1, t2)
        d1, d2 = max(x1, 0.0), min(x2, depth_end_mm)
        if d1 < d2 or (d1 == d2 and x2 > 0.0 and x1 < depth_end_mm):
            gaps.append(SliceGap(float(pos[k]), float(pos[k + 1]), step, d1, d2))
    return tuple(gaps)


def check_padding(
    volume: CTVolume,
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    drill: DrillSpec,
    lip: LipSamples,
    n_rings: int,
    n_angles: int,
    *,
    name: str = "",
    holes: Sequence[Hole] = (),
) -> None:
    """Refuse a path whose lip samples at or ahead of the entry touch padding inside the grid
    (only depths where the sampler counted samples outside or on padding are looked at again;
    ``holes`` as given to the sampler, so the same points). Samples behind the entry (the lip
    of the first ``l_t`` mm, not yet in contact) are not cut: padding there is read as air."""
    flagged = np.flatnonzero(lip.outside > 0)
    if volume.valid is None or flagged.size == 0:
        return
    points = lip_ring_points(
        entry_lps,
        target_lps,
        lip.depth_mm[flagged],
        drill,
        n_rings=n_rings,
        n_angles=n_angles,
        holes=holes,
    )
    depth = np.broadcast_to(lip.depth_mm[flagged][:, None, None], points.shape[:3]).reshape(-1)
    points = points.reshape(-1, 3)
    ahead = (points - np.asarray(entry_lps, dtype=np.float64)) @ axis_basis(entry_lps, target_lps)[
        0
    ] >= -1e-9
    idx = volume.lps_to_index(points)
    n_s, n_r, n_c = volume.hu.shape
    sizes = np.array([n_c, n_r, n_s], dtype=np.float64)
    with np.errstate(invalid="ignore"):
        in_grid = np.all((idx >= -1e-6) & (idx <= sizes - 1.0 + 1e-6), axis=1)
    on_padding = in_grid & ~volume.inside(points) & ahead
    if on_padding.any():
        hit = depth[on_padding]
        raise PathInputError(
            f"plan {name!r}: the drill lip crosses padding (pixels outside the scanner's "
            f"reconstruction field, {int(on_padding.sum())} lip samples at tip depths "
            f"{_mm(float(hit.min()))}..{_mm(float(hit.max()))} mm); the CT holds no data "
            "there: move the trajectory into the reconstructed field"
        )
