"""ctdrill imaging: DICOM CT series -> :class:`CTVolume` (LPS mm), sampling, plans, safety."""

from imaging.errors import ImagingInputError
from imaging.volume import WARNING_CODES, CTVolume, LoadWarning, SeriesInfo

__all__ = [
    "WARNING_CODES",
    "CTVolume",
    "ImagingInputError",
    "LoadWarning",
    "SeriesInfo",
]
