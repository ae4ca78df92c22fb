"""The bone along a path: the Misch share of its depths and the mean HU of equal segments.

A segment's mean HU is the integral mean of the lip-mean HU over it: the exact integral of
the profile's piecewise-linear interpolant (the profile is linear between its grid depths, as
the force is), divided by the segment's length.
"""

from __future__ import annotations

import itertools

import numpy as np

from ctdrill.engine.summary import HuGrading, HuSegment
from ctdrill.imaging.misch import MISCH_CLASSES, misch_class

#: Equal segments of the path the summary gives the mean HU of.
N_HU_SEGMENTS = 10


def interpolant_integral(depth_mm: np.ndarray, values: np.ndarray, x_mm: np.ndarray) -> np.ndarray:
    """``int_{depth_0}^{x} f`` of the piecewise-linear ``f`` through ``(depth_mm, values)``
    at each ``x`` (within the grid), exactly.

    Parameters
    ----------
    depth_mm : (D,) increasing grid, mm.
    values : (D,) the function at the grid depths.
    x_mm : (P,) where to evaluate, mm.
    """
    cum = np.concatenate([[0.0], np.cumsum(0.5 * np.diff(depth_mm) * (values[1:] + values[:-1]))])
    k = np.clip(np.searchsorted(depth_mm, x_mm, side="right") - 1, 0, depth_mm.size - 2)
    f_x = np.interp(x_mm, depth_mm, values)
    out: np.ndarray = cum[k] + 0.5 * (x_mm - depth_mm[k]) * (values[k] + f_x)
    return out


def hu_grading(depth_mm: np.ndarray, hu_mean: np.ndarray, stop_depth_mm: float) -> HuGrading:
    """Misch share of the path's depths down to the stop depth and the integral mean HU of
    :data:`N_HU_SEGMENTS` equal segments of ``[0, stop]`` (None where the stop is at 0).

    Parameters
    ----------
    depth_mm, hu_mean : (D,) the profile's grid and lip-mean HU.
    stop_depth_mm : where the drill stops, mm.
    """
    keep = depth_mm <= stop_depth_mm + 1e-9
    classes = misch_class(hu_mean[keep])
    share = {c: float(np.mean(classes == c)) if classes.size else 0.0 for c in MISCH_CLASSES}
    edges = np.linspace(0.0, stop_depth_mm, N_HU_SEGMENTS + 1)
    integral = interpolant_integral(depth_mm, hu_mean, edges)
    segments = []
    for (lo, hi), (c_lo, c_hi) in zip(
        itertools.pairwise(edges.tolist()), itertools.pairwise(integral.tolist()), strict=True
    ):
        mean = (c_hi - c_lo) / (hi - lo) if hi > lo else None
        segments.append(
            HuSegment(
                from_mm=round(float(lo), 4),
                to_mm=round(float(hi), 4),
                mean_hu=None if mean is None else round(mean, 2),
                misch=None if mean is None else str(misch_class(np.array([mean]))[0]),
            )
        )
    return HuGrading(misch_share=share, segments=tuple(segments))
