"""ctdrill imaging: DICOM CT series -> :class:`CTVolume` (LPS mm), sampling, plans, safety."""

from ctdrill.imaging.dicom.grey import calibrate_grey_to_hu
from ctdrill.imaging.dicom.resample import resample_uniform_slices
from ctdrill.imaging.dicom.series import DEFAULT_MAX_BYTES, SeriesSummary, list_series, load_series
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.phantom.io import PhantomCase, write_phantom
from ctdrill.imaging.phantom.mandible import Phantom, make_mandible_phantom
from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark, PointLandmark
from ctdrill.imaging.plan.safety import clearance_profile_mm, max_safe_depth_mm
from ctdrill.imaging.plan.types import (
    DrillSpec,
    Plan,
    PlanInputError,
    load_plan,
    load_plans,
    save_plan,
)
from ctdrill.imaging.sampling.lip import LipSamples, lip_ring_points, sample_lip_rings
from ctdrill.imaging.volume import WARNING_CODES, CTVolume, LoadWarning, SeriesInfo

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
