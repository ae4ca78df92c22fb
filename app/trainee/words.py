"""The assessment in plain words, for the trainee's screen and the command line.

The engineering names (the fields of :data:`ctdrill.haptics.assessment.ASSESSMENT_FIELDS`) stay
in ``summary.json`` and the tooltips; these sentences are what a student reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ctdrill.app.trainee.kinds import device_fault_of
from ctdrill.haptics.renderer import CONTINUOUS_FORCE_N
from ctdrill.haptics.score import (
    DEPTH_SCALE_MM,
    HAND_ALLOWED_N,
    PLUNGE_SCALE_MM,
    STEADY_FREE_CV,
    STEADY_SCALE_CV,
    WALL_GRACE_S,
    WALL_OVERRUN_FREE_MM,
    WALL_PRESS_SATURATE_S,
)

#: A hand force varying less than this (coefficient of variation) is "steady" (the score's free
#: band), less than this "fairly steady".
STEADY_CV = STEADY_FREE_CV
FAIRLY_STEADY_CV = STEADY_FREE_CV + STEADY_SCALE_CV / 2.0
#: A reaction slower than this reads as late, ms; a plunge deeper than this as deep, mm.
LATE_REACTION_MS = 300.0
DEEP_PLUNGE_MM = PLUNGE_SCALE_MM
#: A depth within this of the goal is "at the goal", mm.
AT_GOAL_MM = 0.05


@dataclass(frozen=True)
class Line:
    """One sentence of the debrief and the fields it comes from (its tooltip)."""

    text: str
    fields: tuple[str, ...]
    bad: bool = False

    def tooltip(self, assessment: Mapping[str, Any]) -> str:
        """``field = value`` of each field, one a line."""
        return "\n".join(f"{f} = {assessment.get(f)}" for f in self.fields)


def _ending(a: Mapping[str, Any], planned_mm: float, summary: Mapping[str, Any] | None) -> Line:
    """Why the session ended where it did (the depth against the goal)."""
    goal = float(a["goal_depth_mm"])
    err = float(a["depth_error_mm"])
    reached = goal + err
    fields = ("depth_error_mm", "goal_depth_mm", "attempted")
    reason = str((summary or {}).get("reason") or "")
    if summary is not None and device_fault_of(summary):
        return Line(
            f"The session ended on a fault of the device or its link ({reason}), not yours: it "
            "is left out of your grades and curves.",
            fields,
            True,
        )
    if reason.startswith("drill_past_stop"):
        return Line(
            f"The drill went past the device's stop at {reached:.2f} mm and the session was ended.",
            fields,
            True,
        )
    if a["breach"]:
        return Line(
            f"You drilled to {reached:.2f} mm, {err:.2f} mm past the goal ({goal:.2f} mm).",
            fields,
            True,
        )
    if abs(err) < AT_GOAL_MM:
        if int(a["wall_contacts"]) == 0:
            return Line(f"You stopped yourself at the goal, {goal:.2f} mm: correct.", fields)
        where = "at the margin" if goal < planned_mm - AT_GOAL_MM else "at the planned depth"
        return Line(f"The wall stopped you {where}, at {goal:.2f} mm: correct.", fields)
    if err < 0.0:
        text = f"You stopped at {reached:.2f} mm, {-err:.2f} mm short of the goal ({goal:.2f} mm)"
        if not a["attempted"]:
            text += f"; more than {DEPTH_SCALE_MM:g} mm short is not an attempt and not scored"
        return Line(text + ".", fields, not a["attempted"])
    return Line(
        f"You drilled to {reached:.2f} mm, {err:.2f} mm deeper than the goal ({goal:.2f} mm), "
        "and kept the margin.",
        fields,
    )


def _reaction(a: Mapping[str, Any]) -> Line:
    fields = ("reaction_ms", "plunge_mm", "display_lag_ms", "display_lagged")
    r = a["reaction_ms"]
    if r is None:
        return Line("The drill did not break out of the last layer before the goal.", fields)
    if a["display_lagged"]:
        return Line(
            f"The screen lagged by up to {float(a['display_lag_ms']):.0f} ms, so your reaction "
            "is not scored.",
            fields,
            True,
        )
    plunge = float(a["plunge_mm"])
    return Line(
        f"When the bone gave way you let go after {float(r):.0f} ms; the drill went "
        f"{plunge:.2f} mm further.",
        fields,
        float(r) > LATE_REACTION_MS or plunge > DEEP_PLUNGE_MM,
    )


def _pressed(press_s: float, contacts: int) -> str:
    """How long the hand pressed on the wall, in words: the record counts each contact up to
    the grace plus the saturation (a hand still pressing then never let go), so a saturated
    press reads "more than" that."""
    cap_s = (WALL_GRACE_S + WALL_PRESS_SATURATE_S) * max(contacts, 1)
    if press_s >= cap_s - 0.01:
        return f"more than {cap_s:.1f} s"
    return f"{press_s:.1f} s"


def _wall(a: Mapping[str, Any]) -> Line:
    fields = ("wall_contacts", "peak_wall_force_n", "wall_press_s", "wall_overrun_mm")
    n = int(a["wall_contacts"])
    if n == 0:
        return Line("You did not meet the stop.", fields)
    press = float(a["wall_press_s"])
    overrun = float(a["wall_overrun_mm"])
    text = (
        f"You met the stop {'once' if n == 1 else f'{n} times'} and pressed on it for "
        f"{_pressed(press, n)}; "
        f"it pushed back with up to {float(a['peak_wall_force_n']):.1f} N"
    )
    if overrun > WALL_OVERRUN_FREE_MM:
        text += f", and your handle sank {overrun:.1f} mm into it"
    bad = n > 1 or press > WALL_GRACE_S * n or overrun > WALL_OVERRUN_FREE_MM
    return Line(text + ".", fields, bad)


def next_time(a: Mapping[str, Any], summary: Mapping[str, Any] | None = None) -> Line:
    """The one thing to do next time, with numbers (the most important first)."""
    goal = float(a["goal_depth_mm"])
    mean = float(a["mean_hand_force_n"])
    peak = float(a["peak_hand_force_n"])
    push = min(mean, CONTINUOUS_FORCE_N)
    n = max(int(a["wall_contacts"]), 1)
    press = float(a["wall_press_s"])
    cv = a.get("hand_force_cv")
    r = a["reaction_ms"]
    fields: tuple[str, ...] = ("mean_hand_force_n",)
    if summary is not None and device_fault_of(summary):
        text = "rehearse again: this session is not graded"
    elif a["breach"]:
        safe = goal + float(a["depth_error_mm"]) - float(a["overshoot_mm"])
        text = (
            f"let go by {safe:.1f} mm, {float(a['overshoot_mm']):.1f} mm sooner, pushing about "
            f"{push:.0f} N"
        )
        fields = ("overshoot_mm", "mean_hand_force_n")
    elif not a["attempted"]:
        text = f"push harder than {mean:.0f} N and drill on to {goal:.1f} mm"
    elif peak > HAND_ALLOWED_N:
        text = f"push at most {CONTINUOUS_FORCE_N:.0f} N (you pushed up to {peak:.0f} N)"
        fields = ("peak_hand_force_n",)
    elif press > WALL_GRACE_S * n or float(a["wall_overrun_mm"]) > WALL_OVERRUN_FREE_MM:
        text = (
            f"let go within {WALL_GRACE_S:.1f} s of meeting the stop (you pressed "
            f"{_pressed(press, n)})"
        )
        fields = ("wall_press_s",)
    elif r is not None and not a["display_lagged"] and float(r) > LATE_REACTION_MS:
        text = (
            f"let go within {LATE_REACTION_MS:.0f} ms of the bone giving way (you took "
            f"{float(r):.0f} ms)"
        )
        fields = ("reaction_ms",)
    elif cv is not None and float(cv) >= STEADY_CV:
        text = f"hold an even push of about {push:.0f} N"
        fields = ("hand_force_cv", "mean_hand_force_n")
    elif float(a["depth_error_mm"]) < -AT_GOAL_MM:
        short = -float(a["depth_error_mm"])
        text = f"drill {short:.1f} mm deeper, to {goal:.1f} mm, pushing about {push:.0f} N"
        fields = ("depth_error_mm", "mean_hand_force_n")
    else:
        text = f"the same: push about {push:.0f} N and let go at {goal:.1f} mm"
    return Line(f"Next time: {text}.", fields)


def debrief_lines(
    assessment: Mapping[str, Any],
    *,
    planned_depth_mm: float,
    summary: Mapping[str, Any] | None = None,
) -> list[Line]:
    """The assessment as sentences: the score, why the session ended (against the goal), the
    margin, the push and its steadiness, the time to the goal, the reaction, the wall, and
    one "next time" line with numbers. ``summary`` (its ``summary.json``) names faults."""
    a = assessment
    score = (
        Line(f"Score: {a['score']:.0f} of 100", ("score",))
        if a["attempted"] or a["breach"]
        else Line("Not scored: the drill never reached the goal's region.", ("score",), True)
    )
    out = [score, _ending(a, planned_depth_mm, summary)]
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
        out.append(
            Line(
                "You stayed out of the safety zone around the nerve.",
                ("breach", "overshoot_mm", "time_in_margin_s", "canal_entered"),
            )
        )
    peak = float(a["peak_hand_force_n"])
    over = peak > HAND_ALLOWED_N
    out.append(
        Line(
            f"Your push: up to {peak:.1f} N, {float(a['mean_hand_force_n']):.1f} N on average"
            + (f", beyond the device's {CONTINUOUS_FORCE_N:.0f} N rating." if over else "."),
            ("peak_hand_force_n", "mean_hand_force_n"),
            over,
        )
    )
    cv = a.get("hand_force_cv")
    if cv is not None:
        word = (
            "steady" if cv < STEADY_CV else ("fairly steady" if cv < FAIRLY_STEADY_CV else "uneven")
        )
        out.append(
            Line(
                f"Your push was {word} (it varied by {100 * float(cv):.0f} %).",
                ("hand_force_cv", "feed_cv"),
                cv >= FAIRLY_STEADY_CV,
            )
        )
    else:
        out.append(Line("Your push was not measured while cutting.", ("hand_force_cv", "feed_cv")))
    t = a["time_to_planned_s"]
    out.append(
        Line(
            "You did not reach the goal."
            if t is None
            else f"You reached the goal after {float(t):.1f} s.",
            ("time_to_planned_s",),
            t is None,
        )
    )
    out.append(_reaction(a))
    out.append(_wall(a))
    out.append(next_time(a, summary))
    return out


def assessment_line(summary: Mapping[str, Any]) -> str:
    """One line for ``ctdrill rehearse``: the score, the depth and any breach."""
    a = summary["assessment"]
    goal = float(a.get("goal_depth_mm", summary["planned_depth_mm"]))
    breach = (
        f"breach: {float(a['overshoot_mm']):.2f} mm past the max safe depth, "
        f"{float(a['time_in_margin_s']):.2f} s in the margin"
        + (", the canal entered" if a["canal_entered"] else "")
        if a["breach"]
        else "the margin kept"
    )
    return (
        f"assessment: score {a['score']:.1f}/100; drilled to "
        f"{goal + float(a['depth_error_mm']):.2f} mm of the {goal:.2f} mm goal; {breach}"
    )
