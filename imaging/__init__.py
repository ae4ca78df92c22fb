"""ctdrill imaging: DICOM CT series -> :class:`CTVolume` (LPS mm), sampling, plans, safety."""

from imaging._load_calibrate import calibrate_grey_to_hu
from imaging._load_resample import resample_uniform_slices
from imaging.errors import ImagingInputError
from imaging.series import DEFAULT_MAX_BYTES, SeriesSummary, list_series, load_series
from imaging.volume import WARNING_CODES, CTVolume, LoadWarning, SeriesInfo

__all__ = [
    "DEFAULT_MAX_BYTES",
    "WARNING_CODES",
    "CTVolume",
    "ImagingInputError",
    "LoadWarning",
    "SeriesInfo",
    "SeriesSummary",
    "calibrate_grey_to_hu",
    "list_series",
    "load_series",
    "resample_uniform_slices",
]
