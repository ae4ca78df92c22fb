"""ctdrill model package: calibration sets, the force law, profiles, spectral analysis, fitting.

Pure NumPy/SciPy; imports no other ctdrill package.
"""

from ctdrill.model.calibration import (
    Calibration,
    CalibrationError,
    Harmonic,
    PowerLaw,
    available_calibrations,
    harmonic_freqs_hz,
    load_calibration,
)
from ctdrill.model.errors import ModelInputError
from ctdrill.model.fit import CalibrationFit, calibrate_from_manifest, fit_document
from ctdrill.model.force import a0_n, bk_n, c_prime, clip_count, force_density_n, gate
from ctdrill.model.layered import layered_profile
from ctdrill.model.profile import Profile, ProfileInputError, build_profile, force_n, force_series_n
from ctdrill.model.spectral import amplitude_spectrum, extract_components, spectrogram

__all__ = [
    "Calibration",
    "CalibrationError",
    "CalibrationFit",
    "Harmonic",
    "ModelInputError",
    "PowerLaw",
    "Profile",
    "ProfileInputError",
    "a0_n",
    "amplitude_spectrum",
    "available_calibrations",
    "bk_n",
    "build_profile",
    "c_prime",
    "calibrate_from_manifest",
    "clip_count",
    "extract_components",
    "fit_document",
    "force_density_n",
    "force_n",
    "force_series_n",
    "gate",
    "harmonic_freqs_hz",
    "layered_profile",
    "load_calibration",
    "spectrogram",
]
