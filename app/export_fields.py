"""Summary fields derived from a path: the HU grading, the slice gaps interpolated across, the
implant."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from ctdrill.engine.path import PathResult
from ctdrill.imaging.misch import MISCH_CLASSES, misch_class

#: Equal segments of the path the summary gives the mean HU of.
N_HU_SEGMENTS = 10


def hu_grading(result: PathResult) -> dict[str, Any]:
    """Misch share of the path down to the stop depth and mean HU in 10 equal segments."""
    prof = result.profile
    stop = result.stop_depth_mm
    keep = prof.depth_mm <= stop + 1e-9
    classes = misch_class(prof.hu_mean[keep])
    share = {c: float(np.mean(classes == c)) if classes.size else 0.0 for c in MISCH_CLASSES}
    segments = []
    edges = np.linspace(0.0, stop, N_HU_SEGMENTS + 1)
    for lo, hi in itertools.pairwise(edges):
        # mean of the lip-mean HU over [lo, hi], trapezoid on a fine resampling
        xs = np.linspace(lo, hi, 33)
        mean = float(np.mean(np.interp(xs, prof.depth_mm, prof.hu_mean))) if hi > lo else None
        segments.append(
            {
                "from_mm": round(float(lo), 4),
                "to_mm": round(float(hi), 4),
                "mean_hu": None if mean is None else round(mean, 2),
                "misch": None if mean is None else str(misch_class(np.array([mean]))[0]),
            }
        )
    return {"misch_share": share, "segments": segments}


def interpolated_gaps_json(result: PathResult) -> list[dict[str, float]]:
    """The slice gaps interpolated across on request (``--interpolate-gaps``); [] if none."""
    return [
        {
            "lower_mm": round(g.lower_mm, 4),
            "upper_mm": round(g.upper_mm, 4),
            "nominal_step_mm": round(abs(g.nominal_step_mm), 4),
            "depth_from_mm": round(g.depth_from_mm, 4),
            "depth_to_mm": round(g.depth_to_mm, 4),
        }
        for g in result.interpolated_gaps
    ]


def implant_json(result: PathResult) -> dict[str, Any] | None:
    """The summary's ``implant``: its spec and placement (``ImplantPlacement.to_json``) and
    ``seated``: whether the stop reaches its apex (else warning ``implant_beyond_stop``);
    None for a plan without an implant."""
    from ctdrill.imaging.plan.implant_checks import implant_seated
    from ctdrill.imaging.plan.implants import implant_placement

    place = implant_placement(result.plan)
    if place is None:
        return None
    return {**place.to_json(), "seated": implant_seated(place, result.stop_depth_mm)}
