"""The force band of a path: the mean force's 68 % band and what the summary says of it.

The band itself is :func:`ctdrill.model.band.force_band` (68 %, first order in log space, from
the calibration's covariance and an HU uncertainty). It bounds the mean cutting force
``mean_force_n = S0 (1 + Ke v)`` at the export's feed, not ``S0``: profile.csv writes it as
``mean_force_lo_n``, ``mean_force_hi_n`` beside ``mean_force_n`` (:data:`BAND_COLUMNS`). A set
without a covariance gives no band: the two columns stay empty (``mean_force_n`` is always
written) and the summary says why, never a zero-width band.
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.engine.path import PathResult
from ctdrill.engine.summary import ForceBandPeak, HuUncertaintyInfo
from ctdrill.model.band import BAND_LEVEL, ForceBand, HuUncertainty, force_band, lip_sensitivity

#: profile.csv's columns after the DESIGN.md ones: the mean force at the export's feed, its band.
BAND_COLUMNS = ("mean_force_n", "mean_force_lo_n", "mean_force_hi_n")
#: How the band is computed, as the summary says it.
BAND_METHOD = "first-order propagation in log space; band = mean x exp(+-sd)"


def path_band(result: PathResult, feed_mm_s: float, hu: HuUncertainty | None) -> ForceBand | None:
    """The band of ``result``'s mean cutting force at ``feed_mm_s``; None without covariance."""
    sens = lip_sensitivity(result.lip.hu, result.lip.ring_weights, result.calibration)
    return force_band(sens, result.calibration, feed_mm_s, hu, s0_n=result.profile.s0_n)


def _r(v: float, digits: int = 4) -> float | None:
    return round(float(v), digits) if math.isfinite(v) else None


def hu_uncertainty_info(hu: HuUncertainty | None) -> HuUncertaintyInfo | None:
    """What the summary says of the series' HU uncertainty (None without one)."""
    if hu is None:
        return None
    return HuUncertaintyInfo(
        source=hu.source,
        sd_hu_at_0_hu=_r(hu.sd_hu_at(0.0), 3),
        sd_hu_at_1000_hu=_r(hu.sd_hu_at(1000.0), 3),
    )


def band_peak(
    result: PathResult, band: ForceBand | None, hu: HuUncertainty | None
) -> tuple[ForceBandPeak | None, str]:
    """The band at the peak mean force down to the stop depth (None without a band) and the
    note of what it includes, or why there is none."""
    cal = result.calibration
    if band is None:
        low, high = BAND_COLUMNS[1:]
        note = (
            f"no force band: calibration {cal.name!r} gives no parameter covariance, so its "
            f"uncertainty is unknown (profile.csv {low}, {high} are empty)"
        )
        if hu is not None:
            note += "; the HU uncertainty given is recorded but not used alone"
        return None, note
    prof = result.profile
    keep = prof.depth_mm <= result.stop_depth_mm + 1e-9
    i = int(np.argmax(np.where(keep, band.mean_n, -np.inf)))
    parts = "the calibration's covariance"
    parts += (
        f" and the HU uncertainty ({hu.source})"
        if hu is not None
        else "; HU uncertainty not known, not included (give --hu-sigma)"
    )
    peak = ForceBandPeak(
        level=BAND_LEVEL,
        feed_mm_s=band.feed_mm_s,
        method=BAND_METHOD,
        peak_depth_mm=_r(float(prof.depth_mm[i])),
        peak_mean_force_n=_r(float(band.mean_n[i])),
        peak_lo_n=_r(float(band.lo_n[i])),
        peak_hi_n=_r(float(band.hi_n[i])),
        peak_sd_log=_r(float(band.sd_log[i]), 5),
        peak_sd_log_calibration=_r(float(band.sd_log_cal[i]), 5),
        peak_sd_log_hu=_r(float(band.sd_log_hu[i]), 5),
    )
    return peak, f"68 % band of the mean cutting force from {parts}"
