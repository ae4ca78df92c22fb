"""ctdrill imaging: CT (DICOM, NIfTI, NRRD, MetaImage) -> :class:`CTVolume` (LPS mm), sampling,
plans, safety.

The names below are re-exported lazily (PEP 562): ``from ctdrill.imaging import load_series``
imports :mod:`ctdrill.imaging.dicom.series` (and pydicom) only then, so ``import
ctdrill.imaging.errors`` or ``ctdrill --help`` stays light. :data:`_EXPORTS` is the one table of
which module defines each name; the ``TYPE_CHECKING`` imports say the same to mypy
(``tests/test_architecture.py`` checks that the two agree).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctdrill.lazy import attach

if TYPE_CHECKING:
    from ctdrill.imaging.dicom.grey import calibrate_grey_to_hu
    from ctdrill.imaging.dicom.resample import resample_uniform_slices
    from ctdrill.imaging.dicom.series import (
        DEFAULT_MAX_BYTES,
        SeriesSummary,
        list_series,
        load_series,
    )
    from ctdrill.imaging.errors import ImagingInputError
    from ctdrill.imaging.phantom.io import PhantomCase, write_phantom
    from ctdrill.imaging.phantom.mandible import Phantom, make_mandible_phantom
    from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark, PointLandmark
    from ctdrill.imaging.plan.load import load_plan, load_plans
    from ctdrill.imaging.plan.safety import clearance_profile_mm, max_safe_depth_mm
    from ctdrill.imaging.plan.types import DrillSpec, Plan, PlanInputError
    from ctdrill.imaging.plan.write import save_plan
    from ctdrill.imaging.sampling.lip import LipSamples, lip_ring_points, sample_lip_rings
    from ctdrill.imaging.volume import WARNING_CODES, CTVolume, LoadWarning, SeriesInfo
    from ctdrill.imaging.volumes.load import load_ct

#: public name -> the module that defines it (imported on first access)
_EXPORTS: dict[str, str] = {
    "DEFAULT_MAX_BYTES": "ctdrill.imaging.dicom.series",
    "WARNING_CODES": "ctdrill.imaging.volume",
    "CTVolume": "ctdrill.imaging.volume",
    "CanalLandmark": "ctdrill.imaging.plan.landmarks",
    "DrillSpec": "ctdrill.imaging.plan.types",
    "ImagingInputError": "ctdrill.imaging.errors",
    "LipSamples": "ctdrill.imaging.sampling.lip",
    "LoadWarning": "ctdrill.imaging.volume",
    "MaskLandmark": "ctdrill.imaging.plan.landmarks",
    "Phantom": "ctdrill.imaging.phantom.mandible",
    "PhantomCase": "ctdrill.imaging.phantom.io",
    "Plan": "ctdrill.imaging.plan.types",
    "PlanInputError": "ctdrill.imaging.plan.types",
    "PointLandmark": "ctdrill.imaging.plan.landmarks",
    "SeriesInfo": "ctdrill.imaging.volume",
    "SeriesSummary": "ctdrill.imaging.dicom.series",
    "calibrate_grey_to_hu": "ctdrill.imaging.dicom.grey",
    "clearance_profile_mm": "ctdrill.imaging.plan.safety",
    "lip_ring_points": "ctdrill.imaging.sampling.lip",
    "list_series": "ctdrill.imaging.dicom.series",
    "load_ct": "ctdrill.imaging.volumes.load",
    "load_plan": "ctdrill.imaging.plan.load",
    "load_plans": "ctdrill.imaging.plan.load",
    "load_series": "ctdrill.imaging.dicom.series",
    "make_mandible_phantom": "ctdrill.imaging.phantom.mandible",
    "max_safe_depth_mm": "ctdrill.imaging.plan.safety",
    "resample_uniform_slices": "ctdrill.imaging.dicom.resample",
    "sample_lip_rings": "ctdrill.imaging.sampling.lip",
    "save_plan": "ctdrill.imaging.plan.write",
    "write_phantom": "ctdrill.imaging.phantom.io",
}

__all__ = [
    "DEFAULT_MAX_BYTES",
    "WARNING_CODES",
    "CTVolume",
    "CanalLandmark",
    "DrillSpec",
    "ImagingInputError",
    "LipSamples",
    "LoadWarning",
    "MaskLandmark",
    "Phantom",
    "PhantomCase",
    "Plan",
    "PlanInputError",
    "PointLandmark",
    "SeriesInfo",
    "SeriesSummary",
    "calibrate_grey_to_hu",
    "clearance_profile_mm",
    "lip_ring_points",
    "list_series",
    "load_ct",
    "load_plan",
    "load_plans",
    "load_series",
    "make_mandible_phantom",
    "max_safe_depth_mm",
    "resample_uniform_slices",
    "sample_lip_rings",
    "save_plan",
    "write_phantom",
]


__getattr__, __dir__ = attach(__name__, _EXPORTS)
