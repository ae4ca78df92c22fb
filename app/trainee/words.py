"""The assessment in plain words, for the trainee's screen and the command line.

The engineering names (the fields of :data:`ctdrill.haptics.assessment.ASSESSMENT_FIELDS`) stay
in ``summary.json`` and the tooltips; these sentences are what a student reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

#: A feed whose coefficient of variation is below these is "steady" / "fairly steady".
STEADY_CV = 0.25
FAIRLY_STEADY_CV = 0.5


@dataclass(frozen=True)
class Line:
    """One sentence of the debrief and the fields it comes from (its tooltip)."""

    text: str
    fields: tuple[str, ...]
    bad: bool = False

    def tooltip(self, assessment: Mapping[str, Any]) -> str:
        """``field = value`` of each field, one a line."""
        return "\n".join(f"{f} = {assessment.get(f)}" for f in self.fields)


def debrief_lines(assessment: Mapping[str, Any], *, planned_depth_mm: float) -> list[Line]:
    """The assessment as sentences, the score first."""
    a = assessment
    reached = planned_depth_mm + float(a["depth_error_mm"])
    err = float(a["depth_error_mm"])
    how = (
        "on the plan"
        if abs(err) < 0.05
        else (f"{-err:.2f} mm short" if err < 0 else f"{err:.2f} mm too deep")
    )
    out = [
        Line(f"Score: {a['score']:.0f} of 100", ("score",)),
        Line(
            f"You drilled to {reached:.2f} mm; the plan asked for {planned_depth_mm:.2f} mm "
            f"({how}).",
            ("depth_error_mm",),
        ),
    ]
    if a["breach"]:
        text = (
            f"You went {float(a['overshoot_mm']):.2f} mm past the safe depth, into the safety "
            f"zone around the nerve, for {float(a['time_in_margin_s']):.2f} s."
        )
        if a["canal_entered"]:
            text += " The drill entered the canal itself."
        out.append(
            Line(text, ("breach", "overshoot_mm", "time_in_margin_s", "canal_entered"), True)
        )
    else:
        out.append(Line("You stayed out of the safety zone around the nerve.", ("breach",)))
    out.append(
        Line(
            f"Your push: up to {float(a['peak_hand_force_n']):.1f} N, "
            f"{float(a['mean_hand_force_n']):.1f} N on average.",
            ("peak_hand_force_n", "mean_hand_force_n"),
        )
    )
    t = a["time_to_planned_s"]
    out.append(
        Line(
            "You did not reach the end of the planned hole."
            if t is None
            else f"You reached the end of the planned hole after {float(t):.1f} s.",
            ("time_to_planned_s",),
            t is None,
        )
    )
    cv = a["feed_cv"]
    if cv is not None:
        word = (
            "steady" if cv < STEADY_CV else ("fairly steady" if cv < FAIRLY_STEADY_CV else "uneven")
        )
        out.append(
            Line(f"Your advance was {word} (it varied by {100 * float(cv):.0f} %).", ("feed_cv",))
        )
    r = a["reaction_ms"]
    out.append(
        Line(
            "The drill did not break through into softer tissue."
            if r is None
            else f"When the bone gave way you let go after {float(r):.0f} ms.",
            ("reaction_ms",),
            r is not None and float(r) > 300.0,
        )
    )
    n = int(a["wall_contacts"])
    out.append(
        Line(
            "You did not meet the stop."
            if n == 0
            else f"You met the stop {n} time{'s' if n > 1 else ''}; it pushed back with up to "
            f"{float(a['peak_wall_force_n']):.1f} N.",
            ("wall_contacts", "peak_wall_force_n"),
        )
    )
    return out


def assessment_line(summary: Mapping[str, Any]) -> str:
    """One line for ``ctdrill rehearse``: the score, the depth and any breach."""
    a = summary["assessment"]
    planned = float(summary["planned_depth_mm"])
    breach = (
        f"breach: {float(a['overshoot_mm']):.2f} mm past the max safe depth, "
        f"{float(a['time_in_margin_s']):.2f} s in the margin"
        + (", the canal entered" if a["canal_entered"] else "")
        if a["breach"]
        else "the margin kept"
    )
    return (
        f"assessment: score {a['score']:.1f}/100; drilled to "
        f"{planned + float(a['depth_error_mm']):.2f} mm of {planned:.2f} mm planned; {breach}"
    )
