"""The force time series of a path at constant feed: what ``force.csv`` holds."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.engine.errors import ExportInputError
from ctdrill.engine.path import PathResult
from ctdrill.model.profile import force_series_n
from ctdrill.numtext import number_text

#: Most rows of a force.csv (at 1000 Hz, 14 hours of drilling): a rate too high for the feed
#: is refused, not computed.
MAX_FORCE_SAMPLES = 50_000_000


@dataclass(frozen=True)
class ForceSeries:
    """The force time series at constant feed, arrays of shape (T,)."""

    time_s: np.ndarray
    depth_mm: np.ndarray
    hu: np.ndarray
    s_t: np.ndarray
    force_n: np.ndarray
    clearance_mm: np.ndarray


def check_positive(value: float, name: str) -> None:
    """Refuse a feed or rate that is not a positive number (``name`` the option)."""
    if not (math.isfinite(value) and value > 0.0):
        raise ExportInputError(f"{name} must be a positive number, got {value!r}")


def force_time_series(
    result: PathResult, *, feed_mm_s: float, rate_hz: float, feed_option: bool = False
) -> ForceSeries:
    """Constant-feed time series from depth 0 to the stop depth.

    Parameters
    ----------
    result : the path.
    feed_mm_s : feed, mm/s (> 0).
    rate_hz : sample rate, Hz (> 0).
    feed_option : the feed is ``--feed-mm-s``'s (messages name it), not the plan's.

    Returns
    -------
    ForceSeries with ``time_s = i / rate_hz``, ``depth_mm = feed * time_s`` <= stop depth.
    """
    check_positive(feed_mm_s, "--feed-mm-s (feed_mm_s)")
    check_positive(rate_hz, "--rate-hz")
    samples = result.stop_depth_mm / feed_mm_s * rate_hz
    if not samples < MAX_FORCE_SAMPLES:
        plan = result.plan
        whose = "--feed-mm-s" if feed_option else f"plan {plan.name!r}: feed_mm_s"
        raise ExportInputError(
            f"{whose} {number_text(feed_mm_s)} mm/s at --rate-hz {number_text(rate_hz)} gives "
            f"{number_text(samples, 3)} force.csv samples to the stop at "
            f"{number_text(result.stop_depth_mm, 4)} mm, more than the {MAX_FORCE_SAMPLES} "
            "accepted; give a feed in mm/s (0.4 is typical) or lower --rate-hz"
        )
    n = math.floor(samples + 1e-9) + 1
    t = np.arange(n, dtype=np.float64) / rate_hz
    x = np.minimum(feed_mm_s * t, result.stop_depth_mm)
    prof = result.profile
    return ForceSeries(
        time_s=t,
        depth_mm=x,
        hu=np.interp(x, prof.depth_mm, prof.hu_mean),
        s_t=np.interp(x, prof.depth_mm, prof.s_t),
        force_n=force_series_n(prof, x, feed_mm_s, t),
        clearance_mm=np.interp(x, result.depth_mm, result.min_clearance_per_depth_mm),
    )
