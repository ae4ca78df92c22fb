"""ctdrill model package: calibration sets, the force law, profiles, spectral analysis, fitting.

Pure NumPy/SciPy; imports no other ctdrill package.
"""

from model.calibration import (
    Calibration,
    CalibrationError,
    Harmonic,
    PowerLaw,
    available_calibrations,
    harmonic_freqs_hz,
    load_calibration,
)
from model.errors import ModelInputError
from model.force import a0_n, bk_n, c_prime, clip_count, gate
from model.profile import Profile, ProfileInputError, build_profile, force_n, force_series_n

__all__ = [
    "Calibration",
    "CalibrationError",
    "Harmonic",
    "ModelInputError",
    "PowerLaw",
    "Profile",
    "ProfileInputError",
    "a0_n",
    "available_calibrations",
    "bk_n",
    "build_profile",
    "c_prime",
    "clip_count",
    "force_n",
    "force_series_n",
    "gate",
    "harmonic_freqs_hz",
    "load_calibration",
]
