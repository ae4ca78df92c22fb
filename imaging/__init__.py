"""ctdrill imaging: DICOM CT series -> :class:`CTVolume` (LPS mm), sampling, plans, safety."""

from imaging._load_calibrate import calibrate_grey_to_hu
from imaging._load_resample import resample_uniform_slices
from imaging.errors import ImagingInputError
from imaging.landmarks import CanalLandmark, MaskLandmark, PointLandmark
from imaging.lip import LipSamples, lip_ring_points, sample_lip_rings
from imaging.phantom import Phantom, make_mandible_phantom
from imaging.phantom_io import PhantomCase, write_phantom
from imaging.plan import DrillSpec, Plan, PlanInputError, load_plan, load_plans, save_plan
from imaging.safety import clearance_profile_mm, max_safe_depth_mm
from imaging.series import DEFAULT_MAX_BYTES, SeriesSummary, list_series, load_series
from imaging.volume import WARNING_CODES, CTVolume, LoadWarning, SeriesInfo

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
