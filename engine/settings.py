"""How a case is computed and written: one frozen value for every export option.

:class:`ExportSettings` is what ``ctdrill export``, ``report``, ``batch`` and the window pass
instead of loose parameters (the calibration and feed overrides, the force series' rate, the
series to load, patient identifiers, slice gaps, the HU uncertainty and grey map, the plot and
the per-trajectory files). Standard library only: the command-line parsers read its defaults
without loading NumPy.
"""

from __future__ import annotations

from dataclasses import dataclass

#: Sample rate of ``force.csv``, Hz.
DEFAULT_RATE_HZ = 1000.0


@dataclass(frozen=True)
class GreyMapSpec:
    """What ``--grey-to-hu`` / ``--grey-ref`` asked for: numbers, or regions
    ``((x, y, z), r, hu)`` (LPS mm, radius mm, HU)."""

    given: tuple[float, ...] | None = None
    regions: tuple[tuple[tuple[float, float, float], float, float], ...] = ()


@dataclass(frozen=True)
class ExportSettings:
    """Every option of an export (``ctdrill export``, ``report``, ``batch``, the window).

    Attributes
    ----------
    calibration : overrides every plan's calibration (a set name or a JSON path), or None.
    feed_mm_s : overrides every plan's feed, mm/s, or None (each plan's own).
    rate_hz : ``force.csv`` sample rate, Hz.
    series : the series to load: its SeriesInstanceUID or a prefix of its hash (``--series``);
        None: the largest CT series.
    include_phi : write the patient identifiers and the raw series UID.
    interpolate_gaps : interpolate across slice gaps the drill crosses instead of refusing.
    hu_sigma : SD of the series' HU (``--hu-sigma``), entered into every force band.
    grey : a grey-to-HU map applied to the series as loaded, or None.
    plot : write ``force.png``.
    per_trajectory : with several trajectories, also write each one's files.
    placement : overrides every plan's placement mode (``--placement``: ``freehand``,
        ``static``, ``dynamic``, ``robot``; the margin budget's), or None (each plan's own).
    """

    calibration: str | None = None
    feed_mm_s: float | None = None
    rate_hz: float = DEFAULT_RATE_HZ
    series: str | None = None
    include_phi: bool = False
    interpolate_gaps: bool = False
    hu_sigma: float | None = None
    grey: GreyMapSpec | None = None
    plot: bool = True
    per_trajectory: bool = False
    placement: str | None = None

    def feed_for(self, plan_feed_mm_s: float) -> float:
        """The feed of a plan whose own is ``plan_feed_mm_s``: the override, else its own."""
        return plan_feed_mm_s if self.feed_mm_s is None else self.feed_mm_s


#: The settings of an export given no option.
DEFAULTS = ExportSettings()
