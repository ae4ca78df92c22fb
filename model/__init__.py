"""ctdrill model package: calibration sets, the force law, profiles, spectral analysis, fitting.

Pure NumPy/SciPy; imports no other ctdrill package. The names below are re-exported lazily
(PEP 562): each loads its module on first use. :data:`_EXPORTS` is the one table of which
module defines each name; the ``TYPE_CHECKING`` imports say the same to mypy
(``tests/test_architecture.py`` checks that the two agree).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctdrill.lazy import attach

if TYPE_CHECKING:
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
    from ctdrill.model.profile import (
        Profile,
        ProfileInputError,
        build_profile,
        force_n,
        force_series_n,
    )
    from ctdrill.model.spectral import amplitude_spectrum, extract_components, spectrogram

#: public name -> the module that defines it (imported on first access)
_EXPORTS: dict[str, str] = {
    "Calibration": "ctdrill.model.calibration",
    "CalibrationError": "ctdrill.model.calibration",
    "CalibrationFit": "ctdrill.model.fit",
    "Harmonic": "ctdrill.model.calibration",
    "ModelInputError": "ctdrill.model.errors",
    "PowerLaw": "ctdrill.model.calibration",
    "Profile": "ctdrill.model.profile",
    "ProfileInputError": "ctdrill.model.profile",
    "a0_n": "ctdrill.model.force",
    "amplitude_spectrum": "ctdrill.model.spectral",
    "available_calibrations": "ctdrill.model.calibration",
    "bk_n": "ctdrill.model.force",
    "build_profile": "ctdrill.model.profile",
    "c_prime": "ctdrill.model.force",
    "calibrate_from_manifest": "ctdrill.model.fit",
    "clip_count": "ctdrill.model.force",
    "extract_components": "ctdrill.model.spectral",
    "fit_document": "ctdrill.model.fit",
    "force_density_n": "ctdrill.model.force",
    "force_n": "ctdrill.model.profile",
    "force_series_n": "ctdrill.model.profile",
    "gate": "ctdrill.model.force",
    "harmonic_freqs_hz": "ctdrill.model.calibration",
    "layered_profile": "ctdrill.model.layered",
    "load_calibration": "ctdrill.model.calibration",
    "spectrogram": "ctdrill.model.spectral",
}

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


__getattr__, __dir__ = attach(__name__, _EXPORTS)
