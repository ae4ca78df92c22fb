"""Why the drill stops where it does: one :class:`StopReason`, and :func:`stop_words`, the one
function every output (the terminal, ``trajectories.csv``'s lines, the report, the window's
plots, status bar and rehearsal check, a rehearsed sequence's lines) puts a stop into words with.

The stop is ``min(planned depth, max safe depth, where the lip leaves the volume)``
(:mod:`ctdrill.engine.clearance`); ties go to the first reason listed in :class:`StopReason`.
A ``StopReason`` is a ``str`` (``summary.json`` writes its value).
"""

from __future__ import annotations

from enum import StrEnum
from typing import Literal


class StopReason(StrEnum):
    """Why the drill stops (the value is ``summary.json``'s ``stop_reason``)."""

    PLANNED_DEPTH = "planned_depth"
    MARGIN = "margin"
    OUT_OF_VOLUME = "out_of_volume"


#: Each reason in plain words (the report's tables and headings).
_PLAIN = {
    StopReason.PLANNED_DEPTH: "planned depth",
    StopReason.MARGIN: "safety margin",
    StopReason.OUT_OF_VOLUME: "end of the CT",
}

StopForm = Literal["code", "tag", "plain", "sentence"]


def stop_words(
    reason: str,
    *,
    form: StopForm = "tag",
    landmark: str | None = None,
    margin_mm: float | None = None,
    stop_mm: float | None = None,
    planned_mm: float | None = None,
) -> str:
    """A stop in words.

    Parameters
    ----------
    reason : StopReason or its value
    form : str
        ``code``: the reason as written (``margin``); ``tag``: the code and, at a margin, the
        binding landmark and its margin (``margin: 'canal', margin 2 mm``: the terminal);
        ``plain``: plain words (``safety margin``: the report); ``sentence``: the stop and
        where, in a phrase (``the 2.00 mm margin of 'canal' at 10.80 mm (of 12.60 mm
        planned)``: the window), which needs ``stop_mm`` and ``planned_mm``.
    landmark, margin_mm : the binding landmark's name and margin (mm), when known.
    stop_mm, planned_mm : the stop depth and the planned depth, mm (``sentence``).
    """
    why = StopReason(reason)
    if form == "code":
        return why.value
    if form == "plain":
        return _PLAIN[why]
    if form == "tag":
        if why is StopReason.MARGIN and landmark is not None and margin_mm is not None:
            return f"{why.value}: {landmark!r}, margin {margin_mm:g} mm"
        return why.value
    stop = float("nan") if stop_mm is None else stop_mm
    planned = float("nan") if planned_mm is None else planned_mm
    if why is StopReason.PLANNED_DEPTH:
        return f"the planned depth {planned:.2f} mm"
    if why is StopReason.OUT_OF_VOLUME:
        return f"the end of the CT data at {stop:.2f} mm (the drill would leave the scan)"
    if landmark is None or margin_mm is None:
        return f"the safety margin at {stop:.2f} mm"
    return (
        f"the {margin_mm:.2f} mm margin of {landmark!r} at {stop:.2f} mm "
        f"(of {planned:.2f} mm planned)"
    )
