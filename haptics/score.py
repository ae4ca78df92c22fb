"""The score of a rehearsal's assessment, 0-100 (docs/rehearse.md, "The score").

:func:`score_of` is a pure function of an assessment's fields (``summary.json``
``assessment``, a row of the trainee record): anyone holding them recomputes it. Its
properties (tests/haptics/test_score_properties.py holds them over synthetic sessions):

* a session that never reached the goal region (``attempted`` false) scores 0 and is reported
  apart: it never ranks above an attempted session;
* a session that breached the margin scores at most :data:`BREACH_CEILING`, below any
  attempted session that kept it (:data:`SAFE_FLOOR` and up); deeper overshoot never scores
  higher, all else equal;
* the depth term measures the deepest drill against the goal (``goal_depth_mm``: the planned
  drilled depth or the max safe depth, whichever comes first), so a perfect guarded session
  scores 100 on every case;
* pushing beyond the device's continuous rating, pressing on the wall (longer than a reaction
  or through it) and plunging after the breakthrough cost points; steadiness is the variation
  of the hand's force, not of the feed (which follows the bone's layers);
* every field the score reads stops changing after the session's last cutting event: resting,
  retracting, waiting and holding a constant push against the wall change nothing (pressing
  on the wall saturates :data:`WALL_PRESS_SATURATE_S` after the grace; a hand that never let
  go after the breakthrough takes the whole reaction term), so the score does not depend on
  the session's length.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ctdrill.haptics.renderer import CONTINUOUS_FORCE_N

# A session that keeps the margin scores SAFE_FLOOR + (100 - SAFE_FLOOR) * depth * (1 + skill) / 2;
# one that breaches at most BREACH_CEILING, below any attempted session that keeps it.
SAFE_FLOOR = 50.0
BREACH_CEILING = 45.0
#: The score of a session that never reached the goal region (``attempted`` false).
UNATTEMPTED_SCORE = 0.0
#: A depth error this large (either way) takes the whole depth term, mm; a session whose
#: deepest drill stayed this far short of the goal never reached the goal region.
DEPTH_SCALE_MM = 3.0
#: A reaction this slow takes the whole reaction term, ms.
REACTION_SCALE_MS = 1000.0
#: A breaching session's score is divided by ``1 + overshoot / this``, mm ...
OVERSHOOT_SCALE_MM = 2.0
#: ... and multiplied by this when the canal itself was entered.
CANAL_FACTOR = 0.6
#: The hand's force may vary this much (coefficient of variation) at no cost: the device's
#: reading of a constant push varies by a few percent where the bone's layers change ...
STEADY_FREE_CV = 0.05
#: ... and this much more takes the whole steadiness term.
STEADY_SCALE_CV = 0.25
#: Pressing on the stop's wall is free for this long per contact (a reaction to the wall), s ...
WALL_GRACE_S = 0.5
#: ... pressing counts for at most this much longer per contact, s (two of the hand's 50 ms
#: windows: a hand still on the wall then has shown it will not let go within a reaction, and
#: pressing longer is waiting, which must not change the score: the cost saturates) ...
WALL_PRESS_SATURATE_S = 0.1
#: ... and each further this-many seconds of it takes a contact's wall term down by one more
#: share (``1 / (1 + press / this)``: a saturated contact halves it), s.
WALL_PRESS_SCALE_S = 0.1
#: The handle may sink this far past the stopped drill into the wall at no cost (the wall's
#: stiffness under a firm push), mm; each further this-many mm halves the wall term.
WALL_OVERRUN_FREE_MM = 2.0
WALL_OVERRUN_SCALE_MM = 2.0
#: A push's peak reading may exceed the device's continuous rating by this much at no cost,
#: N: the reading's error where the handle meets the wall (measured: a steady 19 N push peaks
#: at 20.3 N over 50 ms there, a 12 N push at 12.2 N on the demo's margin) ...
HAND_READING_TOLERANCE_N = 1.5
#: ... and this much more takes the whole hand term, N (a 30 N push takes it all).
HAND_EXCESS_SCALE_N = 8.0
#: The largest peak reading that costs nothing, N.
HAND_ALLOWED_N = CONTINUOUS_FORCE_N + HAND_READING_TOLERANCE_N
#: Each this-many mm the drill advanced after the breakthrough halves the plunge term, mm.
PLUNGE_SCALE_MM = 1.0


def _clip01(x: float) -> float:
    return min(1.0, max(0.0, x))


def _num(fields: Mapping[str, Any], name: str, default: float = 0.0) -> float:
    value = fields.get(name)
    return default if value is None else float(value)


def score_terms(fields: Mapping[str, Any]) -> dict[str, float]:
    """The score's terms, each 0..1 (1 is best), from an assessment's fields:

    * ``depth``: ``1 - |depth_error_mm| / 3 mm`` (the error against the goal);
    * ``steady``: ``1 - max(hand_force_cv - 0.05, 0) / 0.25`` (1 without a measured push);
    * ``reaction``: ``1 - reaction_ms / 1000 ms`` (1 without a breakthrough, or when the
      display lagged: ``display_lagged``);
    * ``plunge``: ``1 / (1 + plunge_mm / 1 mm)``;
    * ``wall``: ``1 / (1 + max(wall_press_s - 0.5 s * contacts, 0) / 0.1 s) / (1 +
      max(wall_overrun_mm - 2 mm, 0) / 2 mm) / max(wall_contacts, 1)``;
    * ``hand``: ``1 - max(peak_hand_force_n - 21.5 N, 0) / 8 N`` (a push beyond the device's
      continuous rating, 20 N, and the reading's 1.5 N error at the wall).
    """
    cv = fields.get("hand_force_cv")
    react = fields.get("reaction_ms")
    contacts = max(int(_num(fields, "wall_contacts")), 1)
    press = max(_num(fields, "wall_press_s") - WALL_GRACE_S * contacts, 0.0)
    overrun = max(_num(fields, "wall_overrun_mm") - WALL_OVERRUN_FREE_MM, 0.0)
    excess = max(_num(fields, "peak_hand_force_n") - HAND_ALLOWED_N, 0.0)
    reaction = 1.0
    if react is not None and not fields.get("display_lagged"):
        reaction = _clip01(1.0 - float(react) / REACTION_SCALE_MS)
    return {
        "depth": _clip01(1.0 - abs(_num(fields, "depth_error_mm")) / DEPTH_SCALE_MM),
        "steady": 1.0
        if cv is None
        else _clip01(1.0 - max(float(cv) - STEADY_FREE_CV, 0.0) / STEADY_SCALE_CV),
        "reaction": reaction,
        "plunge": 1.0 / (1.0 + max(_num(fields, "plunge_mm"), 0.0) / PLUNGE_SCALE_MM),
        "wall": 1.0
        / (1.0 + press / WALL_PRESS_SCALE_S)
        / (1.0 + overrun / WALL_OVERRUN_SCALE_MM)
        / contacts,
        "hand": _clip01(1.0 - excess / HAND_EXCESS_SCALE_N),
    }


def skill_of(terms: Mapping[str, float]) -> float:
    """``(steady + reaction + plunge) / 3 * wall * hand``, 0..1: the wall and the hand's
    excess scale the whole (pushing through the wall is not made up by a steady hand)."""
    return (
        (terms["steady"] + terms["reaction"] + terms["plunge"])
        / 3.0
        * terms["wall"]
        * terms["hand"]
    )


def score_of(fields: Mapping[str, Any]) -> float:
    """The score, 0-100, of an assessment's fields (``score`` itself is not read).

    ``attempted`` false: :data:`UNATTEMPTED_SCORE`. Kept the margin (``breach`` false):
    ``50 + 50 depth (1 + skill) / 2``, 50 to 100, the top only for a hole to the goal.
    Breached: ``45 (1 + skill) / 2 / (1 + overshoot_mm / 2 mm)``, times 0.6 when the canal
    itself was entered: at most 45, below any attempted session that kept the margin. Terms:
    :func:`score_terms`, skill: :func:`skill_of`. Rounded to 0.1.
    """
    breach = bool(fields["breach"])
    if not breach and not fields.get("attempted", True):
        return UNATTEMPTED_SCORE
    terms = score_terms(fields)
    skill = skill_of(terms)
    if not breach:
        return round(SAFE_FLOOR + (100.0 - SAFE_FLOOR) * terms["depth"] * (1.0 + skill) / 2.0, 1)
    over = max(float(fields["overshoot_mm"]), 0.0)
    score = BREACH_CEILING * (1.0 + skill) / 2.0 / (1.0 + over / OVERSHOOT_SCALE_MM)
    if fields["canal_entered"]:
        score *= CANAL_FACTOR
    return round(score, 1)
