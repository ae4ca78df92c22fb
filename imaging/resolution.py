"""What a CT's sampling lets a clearance claim: the ``coarse_voxels`` load warning, the
accuracy clearances are limited to, and how many digits they are printed with.

**Accuracy.** A surface (the canal's wall, the bone's edge) found on a grid sampled every ``h``
is placed to within ``h / 2``; a slice thicker than its step blurs over its thickness. So a
clearance measured on a CT is known to about half its **coarsest sampling**, the largest of
the in-plane spacing (rows, columns), the slice step and the slice thickness
(:func:`clearance_accuracy_mm`): +-0.2 mm on 0.4 mm voxels, +-2.5 mm on 5 mm slices.

**Coarse voxels** (:func:`coarse_voxels_warning`, load warning ``coarse_voxels``): a slice
step or slice thickness above :data:`COARSE_SLICE_MM` (1.25 mm), or an in-plane spacing above
:data:`COARSE_IN_PLANE_MM` (0.5 mm). Implant planning needs sub-millimetre data (CBCT is
typically 0.1-0.4 mm, dental CT 0.5-1 mm slices); beyond these a 2 mm margin is of the order
of the data's own uncertainty.

**Digits** (:func:`clearance_decimals`, :func:`format_clearance_mm`, the one owner for every
printed clearance): the last printed digit is the largest power of ten not above the accuracy,
``decimals = -floor(log10(accuracy))``, between 0 and :data:`MAX_DECIMALS`: one decimal on
0.3-1 mm voxels (accuracy 0.15-0.5 mm), none on 5 mm slices, two on 0.1 mm micro-CT.
Machine-readable outputs (JSON, CSV) keep every digit; only text for people is rounded.
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.imaging.provenance import LoadWarning
from ctdrill.imaging.stack import median
from ctdrill.imaging.volume import CTVolume

#: A slice step or slice thickness above this is coarse, mm.
COARSE_SLICE_MM = 1.25
#: An in-plane (row or column) spacing above this is coarse, mm.
COARSE_IN_PLANE_MM = 0.5
#: Spacings within this of a limit count as on it (a header's 0.5 read as 0.50000001), mm.
_LIMIT_TOL_MM = 1e-6
#: Most decimals a clearance is printed with (a micrometre).
MAX_DECIMALS = 3


def clearance_accuracy_mm(
    in_plane_mm: float, slice_step_mm: float | None, slice_thickness_mm: float | None = None
) -> float:
    """Half the coarsest sampling: what a clearance on this grid is known to, +- mm.

    Parameters
    ----------
    in_plane_mm : the larger of the row and column spacings, mm.
    slice_step_mm : distance between slices along their normal, mm (None for one slice).
    slice_thickness_mm : nominal slice thickness, mm (None when the header gives none).
    """
    parts = [in_plane_mm, slice_step_mm, slice_thickness_mm]
    return 0.5 * max(abs(float(v)) for v in parts if v is not None)


def grid_sampling_mm(
    affine_lps: np.ndarray, slice_positions_mm: np.ndarray, slice_thickness_mm: float | None
) -> tuple[float, float | None, float | None]:
    """``(in-plane spacing, slice step, slice thickness)`` of a grid, mm: the larger of the
    row and column spacings (the affine's first two columns), the median step of the slice
    positions along their normal (None for one slice), the header's thickness (None when
    absent or not positive)."""
    in_plane = float(np.linalg.norm(np.asarray(affine_lps)[:3, :2], axis=0).max())
    steps = np.abs(np.diff(np.asarray(slice_positions_mm, dtype=np.float64)))
    step = median(steps) if steps.size else None
    thick = slice_thickness_mm
    return in_plane, step, None if thick is None or not thick > 0 else float(thick)


def volume_sampling_mm(volume: CTVolume) -> tuple[float, float | None, float | None]:
    """:func:`grid_sampling_mm` of ``volume``."""
    return grid_sampling_mm(
        volume.affine_lps, volume.slice_positions_mm, volume.info.slice_thickness_mm
    )


def volume_clearance_accuracy_mm(volume: CTVolume) -> float:
    """:func:`clearance_accuracy_mm` of ``volume``'s sampling, +- mm."""
    return clearance_accuracy_mm(*volume_sampling_mm(volume))


def coarse_voxels_warning(
    in_plane_mm: float, slice_step_mm: float | None, slice_thickness_mm: float | None = None
) -> LoadWarning | None:
    """``coarse_voxels`` naming the coarse spacing and the accuracy it limits clearances to,
    or None when the sampling is fine enough (module docstring)."""
    coarse = []
    if slice_step_mm is not None and abs(slice_step_mm) > COARSE_SLICE_MM + _LIMIT_TOL_MM:
        coarse.append(f"slice step {abs(slice_step_mm):.3g} mm")
    if slice_thickness_mm is not None and slice_thickness_mm > COARSE_SLICE_MM + _LIMIT_TOL_MM:
        coarse.append(f"slice thickness {slice_thickness_mm:.3g} mm")
    if in_plane_mm > COARSE_IN_PLANE_MM + _LIMIT_TOL_MM:
        coarse.append(f"in-plane spacing {in_plane_mm:.3g} mm")
    if not coarse:
        return None
    acc = clearance_accuracy_mm(in_plane_mm, slice_step_mm, slice_thickness_mm)
    return LoadWarning(
        "coarse_voxels",
        f"coarse voxels: {', '.join(coarse)} (above {COARSE_SLICE_MM:g} mm between or across "
        f"slices, {COARSE_IN_PLANE_MM:g} mm in plane): clearances and walls measured on it are "
        f"known only to about +-{acc:.2g} mm, printed to {_step_text(acc)}; use a thinner "
        "reconstruction (CBCT or sub-millimetre slices) for implant planning",
    )


def volume_coarse_warning(volume: CTVolume) -> LoadWarning | None:
    """:func:`coarse_voxels_warning` of ``volume``'s sampling."""
    return coarse_voxels_warning(*volume_sampling_mm(volume))


def clearance_decimals(accuracy_mm: float) -> int:
    """Decimals a clearance known to +- ``accuracy_mm`` is printed with (module docstring)."""
    if not (math.isfinite(accuracy_mm) and accuracy_mm > 0.0):
        return MAX_DECIMALS
    return min(MAX_DECIMALS, max(0, -math.floor(math.log10(accuracy_mm) + 1e-9)))


def format_clearance_mm(value_mm: float, accuracy_mm: float) -> str:
    """``value_mm`` with :func:`clearance_decimals` digits, without a unit (``"2.1"``)."""
    return f"{value_mm:.{clearance_decimals(accuracy_mm)}f}"


def _step_text(accuracy_mm: float) -> str:
    d = clearance_decimals(accuracy_mm)
    return "whole millimetres" if d == 0 else f"{10.0**-d:g} mm"
