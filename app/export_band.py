"""The force band in the outputs: profile.csv's columns, the summary's statement at the peak.

The band itself is :func:`ctdrill.model.band.force_band` (68 %, first order in log space, from
the calibration's covariance and an HU uncertainty). A set without a covariance gives no band:
the columns stay empty and the summary says why (docs/export.md), never a zero-width band.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.engine.path import PathResult
from ctdrill.model.band import BAND_LEVEL, ForceBand, HuUncertainty, force_band, lip_sensitivity

#: Largest --hu-sigma accepted, HU: beyond it the CT numbers carry no information.
MAX_HU_SIGMA = 1000.0
#: profile.csv columns after the DESIGN.md ones: the mean force at the export's feed, its band.
BAND_COLUMNS = ("mean_force_n", "s0_lo_n", "s0_hi_n")


def path_band(result: PathResult, feed_mm_s: float, hu: HuUncertainty | None) -> ForceBand | None:
    """The band of ``result``'s mean cutting force at ``feed_mm_s``; None without covariance."""
    sens = lip_sensitivity(result.lip.hu, result.lip.ring_weights, result.calibration)
    return force_band(sens, result.calibration, feed_mm_s, hu, s0_n=result.profile.s0_n)


def _r(v: float, digits: int = 4) -> float | None:
    return round(float(v), digits) if math.isfinite(v) else None


def band_summary(
    result: PathResult,
    band: ForceBand | None,
    *,
    feed_mm_s: float,
    hu: HuUncertainty | None,
) -> dict[str, Any]:
    """``force_band`` (the band at the peak mean force down to the stop depth, or None),
    ``force_band_note`` (what the band includes, or why there is none) and ``hu_uncertainty``
    (its source and SD, or None)."""
    cal = result.calibration
    hu_doc = None
    if hu is not None:
        hu_doc = {
            "source": hu.source,
            "sd_hu_at_0_hu": _r(hu.sd_hu_at(0.0), 3),
            "sd_hu_at_1000_hu": _r(hu.sd_hu_at(1000.0), 3),
        }
    if band is None:
        note = (
            f"no force band: calibration {cal.name!r} gives no parameter covariance, so its "
            "uncertainty is unknown (profile.csv s0_lo_n, s0_hi_n are empty)"
        )
        if hu is not None:
            note += "; the HU uncertainty given is recorded but not used alone"
        return {"force_band": None, "force_band_note": note, "hu_uncertainty": hu_doc}
    prof = result.profile
    keep = prof.depth_mm <= result.stop_depth_mm + 1e-9
    i = int(np.argmax(np.where(keep, band.mean_n, -np.inf)))
    parts = "the calibration's covariance"
    parts += (
        f" and the HU uncertainty ({hu.source})"
        if hu is not None
        else "; HU uncertainty not known, not included (give --hu-sigma)"
    )
    return {
        "force_band": {
            "level": BAND_LEVEL,
            "feed_mm_s": band.feed_mm_s,
            "method": "first-order propagation in log space; band = mean x exp(+-sd)",
            "peak_depth_mm": _r(float(prof.depth_mm[i])),
            "peak_mean_force_n": _r(float(band.mean_n[i])),
            "peak_lo_n": _r(float(band.lo_n[i])),
            "peak_hi_n": _r(float(band.hi_n[i])),
            "peak_sd_log": _r(float(band.sd_log[i]), 5),
            "peak_sd_log_calibration": _r(float(band.sd_log_cal[i]), 5),
            "peak_sd_log_hu": _r(float(band.sd_log_hu[i]), 5),
        },
        "force_band_note": f"68 % band of the mean cutting force from {parts}",
        "hu_uncertainty": hu_doc,
    }


def band_line(doc: dict[str, Any]) -> str:
    """One terminal line: the band at the peak, or why there is none."""
    band = doc.get("force_band")
    if band is None:
        return str(doc.get("force_band_note", "no force band"))
    return (
        f"peak mean force {band['peak_mean_force_n']:.2f} N at {band['peak_depth_mm']:.2f} mm, "
        f"68 % band {band['peak_lo_n']:.2f}-{band['peak_hi_n']:.2f} N "
        f"(at {band['feed_mm_s']:g} mm/s; {doc['force_band_note'].split(' from ', 1)[-1]})"
    )


def hu_uncertainty_option(hu_sigma: float | None) -> HuUncertainty | None:
    """``--hu-sigma``'s HU uncertainty (None when not given); a bad value is exit 2."""
    if hu_sigma is None:
        return None
    if not (math.isfinite(hu_sigma) and 0.0 <= hu_sigma <= MAX_HU_SIGMA):
        raise AppInputError(
            f"--hu-sigma must be a number of HU in [0, {MAX_HU_SIGMA:g}], got {hu_sigma!r}"
        )
    return HuUncertainty.offset(hu_sigma, f"--hu-sigma {hu_sigma:g} HU")
