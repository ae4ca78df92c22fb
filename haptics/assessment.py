"""How a rehearsal went: the ``assessment`` of ``summary.json`` and its score (docs/rehearse.md).

:class:`Assessor` reads a session's telemetry sample by sample (constant memory, any length) and
gives an :class:`Assessment`, whose fields are fixed (:data:`ASSESSMENT_FIELDS`). The score is
:func:`score_of`, a pure function of those fields alone: anyone holding ``summary.json`` (or a
row of the trainee record) recomputes it.

Depths are the drill's (``drill_mm``: it never passes the device's stop); the hand force is the
device's reading of the hand (telemetry ``force_est_n``, the name :mod:`ctdrill.app.readout`
gives it); the breakthrough is the table's (:func:`ctdrill.haptics.hands.first_breakthrough_mm`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.hands import first_breakthrough_mm
from ctdrill.haptics.plant import COULOMB_N
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState
from ctdrill.haptics.renderer import CONTINUOUS_FORCE_N, PEAK_FORCE_N

#: The fields of ``summary.json`` ``assessment``, in order (a contract: docs/rehearse.md).
ASSESSMENT_FIELDS = (
    "depth_error_mm",
    "overshoot_mm",
    "breach",
    "time_in_margin_s",
    "canal_entered",
    "peak_hand_force_n",
    "mean_hand_force_n",
    "time_to_planned_s",
    "feed_cv",
    "reaction_ms",
    "wall_contacts",
    "peak_wall_force_n",
    "score",
)
#: The fields that are booleans, whole numbers, and may be null (the others are finite numbers).
BOOL_FIELDS = ("breach", "canal_entered")
INT_FIELDS = ("wall_contacts",)
NULLABLE_FIELDS = ("time_to_planned_s", "feed_cv", "reaction_ms")
#: A drill depth counts as beyond the max safe depth (or at a goal) past this tolerance, mm:
#: the device holds its stop in float32 (a 10.8 mm stop reads 10.7999992 mm) and its encoder
#: counts 0.1 um.
DEPTH_TOLERANCE_MM = 1e-3
#: The hand has let go once the device reads it below this force, N (the master's Coulomb
#: friction: less does not move it).
LET_GO_N = COULOMB_N
#: The master is in contact with the stop's wall when beyond the drill by more than this, mm.
WALL_CONTACT_MM = 1e-4
#: The feed is measured over windows of this much session time, s.
FEED_WINDOW_S = 0.1
#: The hand's peak force is the largest mean of the device's reading over this much session
#: time, s: a person's push (voluntary force control reaches about 10 Hz), not the reaction
#: observer's few-millisecond transients where the push steps or the handle meets the wall
#: (a steady 12 N push reads up to 16 N for a millisecond at the stop).
HAND_PEAK_WINDOW_S = 0.05

# The score (docs/rehearse.md, "The score"): a session that keeps the margin scores
# SAFE_FLOOR + (100 - SAFE_FLOOR) * q; one that breaches at most BREACH_CEILING, below any
# session that keeps it.
SAFE_FLOOR = 50.0
BREACH_CEILING = 45.0
#: A depth error this large (either way) takes the whole depth term, mm.
DEPTH_SCALE_MM = 3.0
#: A reaction this slow takes the whole reaction term, ms.
REACTION_SCALE_MS = 1000.0
#: A breaching session's score is divided by ``1 + overshoot / this``, mm ...
OVERSHOOT_SCALE_MM = 2.0
#: ... by ``1 + time in the margin / this``, s ...
MARGIN_TIME_SCALE_S = 5.0
#: ... and multiplied by this when the canal itself was entered.
CANAL_FACTOR = 0.6


@dataclass(frozen=True)
class AssessmentContext:
    """What the plan says a session is measured against.

    Attributes
    ----------
    planned_depth_mm : ``|target - entry|``, mm.
    max_safe_depth_mm : the deepest depth keeping every margin, mm.
    goal_depth_mm : the planned osteotomy's end as the plan allows it (the planned depth, or
        the guarded stop where the margin or the volume's end comes first), mm.
    clearance_depth_mm, clearance_mm : (D,) the depths and the smallest signed clearance to a
        landmark there (negative inside one), mm; empty without landmarks.
    """

    planned_depth_mm: float
    max_safe_depth_mm: float
    goal_depth_mm: float
    clearance_depth_mm: np.ndarray
    clearance_mm: np.ndarray

    def clearance_at_mm(self, depth_mm: float) -> float | None:
        """Smallest clearance with the tip at ``depth_mm`` (linear, clamped), mm; None without
        landmarks."""
        if self.clearance_mm.size == 0:
            return None
        return float(np.interp(depth_mm, self.clearance_depth_mm, self.clearance_mm))


@dataclass(frozen=True)
class Assessment:
    """The ``assessment`` of a session (docs/rehearse.md; :data:`ASSESSMENT_FIELDS`)."""

    depth_error_mm: float
    overshoot_mm: float
    breach: bool
    time_in_margin_s: float
    canal_entered: bool
    peak_hand_force_n: float
    mean_hand_force_n: float
    time_to_planned_s: float | None
    feed_cv: float | None
    reaction_ms: float | None
    wall_contacts: int
    peak_wall_force_n: float
    score: float

    def to_json(self) -> dict[str, Any]:
        """The fields in :data:`ASSESSMENT_FIELDS` order (JSON-ready, finite or null)."""
        return asdict(self)


def _clip01(x: float) -> float:
    return min(1.0, max(0.0, x))


def score_terms(fields: Mapping[str, Any]) -> dict[str, float]:
    """The score's terms, each 0..1 (1 is best), from an assessment's fields:

    * ``depth``: ``1 - |depth_error_mm| / 3 mm``;
    * ``steady``: ``1 / (1 + feed_cv)`` (1 without a measured feed);
    * ``reaction``: ``1 - reaction_ms / 1000 ms`` (1 without a breakthrough);
    * ``wall``: ``(1 - peak_wall_force_n / 78 N) / max(wall_contacts, 1)``;
    * ``hand``: ``1 - max(peak_hand_force_n - 20 N, 0) / 58 N`` (a push beyond the device's
      continuous rating costs).
    """
    cv = fields["feed_cv"]
    react = fields["reaction_ms"]
    excess = max(float(fields["peak_hand_force_n"]) - CONTINUOUS_FORCE_N, 0.0)
    return {
        "depth": _clip01(1.0 - abs(float(fields["depth_error_mm"])) / DEPTH_SCALE_MM),
        "steady": 1.0 if cv is None else 1.0 / (1.0 + max(float(cv), 0.0)),
        "reaction": 1.0 if react is None else _clip01(1.0 - float(react) / REACTION_SCALE_MS),
        "wall": _clip01(1.0 - float(fields["peak_wall_force_n"]) / PEAK_FORCE_N)
        / max(int(fields["wall_contacts"]), 1),
        "hand": _clip01(1.0 - excess / (PEAK_FORCE_N - CONTINUOUS_FORCE_N)),
    }


def score_of(fields: Mapping[str, Any]) -> float:
    """The score, 0-100, of an assessment's fields (``score`` itself is not read).

    With the terms of :func:`score_terms`, ``skill = (steady + reaction + wall + hand) / 4``.
    A session that kept the margin (``breach`` false) scores ``50 + 50 depth (1 + skill) / 2``:
    50 to 100, and only a hole of the planned depth reaches the top. One that breached scores
    ``45 (1 + skill) / 2 / (1 + overshoot_mm / 2 mm) / (1 + time_in_margin_s / 5 s)``, times
    0.6 when the canal itself was entered: at most 45, below any session that kept the margin.
    Rounded to 0.1.
    """
    terms = score_terms(fields)
    skill = (terms["steady"] + terms["reaction"] + terms["wall"] + terms["hand"]) / 4.0
    if not fields["breach"]:
        return round(SAFE_FLOOR + (100.0 - SAFE_FLOOR) * terms["depth"] * (1.0 + skill) / 2.0, 1)
    over = max(float(fields["overshoot_mm"]), 0.0)
    inside = max(float(fields["time_in_margin_s"]), 0.0)
    score = BREACH_CEILING * (1.0 + skill) / 2.0
    score /= (1.0 + over / OVERSHOOT_SCALE_MM) * (1.0 + inside / MARGIN_TIME_SCALE_S)
    if fields["canal_entered"]:
        score *= CANAL_FACTOR
    return round(score, 1)


def _worst(values: Sequence[float | None]) -> float | None:
    known = [v for v in values if v is not None]
    return max(known) if known else None


def combine_assessments(
    drills: Sequence[Mapping[str, Any]], *, drills_planned: int, planned_depth_mm: float
) -> Assessment:
    """The assessment of a drill sequence from its drills' (each a session's
    ``assessment``, in drilling order; the drills run, ``drills_planned`` in all), with the
    same fields (docs/rehearse.md, "Drill sequences"):

    * ``depth_error_mm``: the final drill's (it drills the implant's bed); a final drill that
      never ran reached 0 mm, so the error is ``-planned_depth_mm``;
    * ``overshoot_mm``, ``peak_hand_force_n``, ``peak_wall_force_n``: the largest;
      ``wall_contacts``: the most of any drill (each drill meets its own stop once when it is
      done well: a sequence is not scored down for having several drills);
      ``feed_cv`` and ``reaction_ms``: the largest known (the least steady drill, the slowest
      reaction), null when no drill has one;
    * ``breach``, ``canal_entered``: any drill's;
    * ``time_in_margin_s``: summed;
    * ``mean_hand_force_n``: the drills' means averaged (each drill one session of the same
      duration);
    * ``time_to_planned_s``: the drills' times to their goals summed, null unless every
      planned drill ran and reached its goal;
    * ``score``: :func:`score_of` of these fields, so a sequence that breached anywhere scores
      below any that kept the margin.

    One drill, the whole plan: the drill's own assessment.
    """
    if not drills or drills_planned < len(drills):
        raise ValueError("give the assessments of the drills run, at most the drills planned")
    final_ran = len(drills) == drills_planned
    times = [d["time_to_planned_s"] for d in drills]
    fields: dict[str, Any] = {
        "depth_error_mm": drills[-1]["depth_error_mm"]
        if final_ran
        else round(-planned_depth_mm, 4),
        "overshoot_mm": max(float(d["overshoot_mm"]) for d in drills),
        "breach": any(bool(d["breach"]) for d in drills),
        "time_in_margin_s": round(sum(float(d["time_in_margin_s"]) for d in drills), 4),
        "canal_entered": any(bool(d["canal_entered"]) for d in drills),
        "peak_hand_force_n": max(float(d["peak_hand_force_n"]) for d in drills),
        "mean_hand_force_n": round(
            sum(float(d["mean_hand_force_n"]) for d in drills) / len(drills), 3
        ),
        "time_to_planned_s": round(sum(times), 4)
        if final_ran and all(t is not None for t in times)
        else None,
        "feed_cv": _worst([d["feed_cv"] for d in drills]),
        "reaction_ms": _worst([d["reaction_ms"] for d in drills]),
        "wall_contacts": max(int(d["wall_contacts"]) for d in drills),
        "peak_wall_force_n": max(float(d["peak_wall_force_n"]) for d in drills),
    }
    return Assessment(**fields, score=score_of(fields))


class Assessor:
    """Reads a session's telemetry (:meth:`add`, block by block) and assesses it
    (:meth:`result`). Times are session times (``session.csv``'s: from the first sample)."""

    def __init__(self, context: AssessmentContext, table: ProfileTable) -> None:
        self.context = context
        self.table = table
        self._rows = np.arange(table.n_steps) * float(table.depth_step_mm)
        self._s0 = table.s0_n.astype(float)
        self.breakthrough_mm = first_breakthrough_mm(table)
        self.t0: float | None = None
        self.last_t = 0.0
        self.deepest_mm = 0.0
        self.t_goal: float | None = None
        self.time_in_margin_s = 0.0
        self.hand_peak = 0.0
        self._hand_window: deque[tuple[float, float]] = deque()
        self._hand_window_sum = 0.0
        self._hand_window_full = False
        self._hand_start_s: float | None = None
        self._hand_short_mean = 0.0
        self.hand_sum = 0.0
        self.hand_count = 0
        self.wall_contacts = 0
        self.wall_peak = 0.0
        self._in_contact = False
        self.t_breakthrough: float | None = None
        self.t_let_go: float | None = None
        # feed windows: start (t, front), whether every sample cut; Welford sums
        self._win: tuple[float, float] | None = None
        self._win_cut = True
        self._feeds = 0
        self._feed_mean = 0.0
        self._feed_m2 = 0.0

    def _s0_at(self, depth_mm: float) -> float:
        return float(np.interp(depth_mm, self._rows, self._s0, left=0.0, right=0.0))

    def add(self, samples: list[TelemetrySample]) -> None:
        """One block of telemetry, oldest first."""
        for s in samples:
            self._add(s)

    def _add(self, s: TelemetrySample) -> None:
        if self.t0 is None:
            self.t0 = s.time_s
        t = s.time_s - self.t0
        dt = max(t - self.last_t, 0.0)
        self.last_t = t
        ctx = self.context
        drill = s.drill_mm
        armed = s.state in (DeviceState.CUTTING, DeviceState.STOPPED)
        if drill > self.deepest_mm:
            self.deepest_mm = drill
        if self.t_goal is None and drill >= ctx.goal_depth_mm - DEPTH_TOLERANCE_MM:
            self.t_goal = t
        if drill > ctx.max_safe_depth_mm + DEPTH_TOLERANCE_MM:
            self.time_in_margin_s += dt
        if armed:
            self._hand(t, s.force_est_n)
            if s.force_est_n >= LET_GO_N:
                self.hand_sum += s.force_est_n
                self.hand_count += 1
        contact = s.state == DeviceState.STOPPED and s.master_mm > drill + WALL_CONTACT_MM
        if s.state == DeviceState.STOPPED:
            self.wall_peak = max(self.wall_peak, s.force_cmd_n)
        if contact and not self._in_contact:
            self.wall_contacts += 1
        self._in_contact = contact
        bt = self.breakthrough_mm
        if (
            self.t_breakthrough is None
            and bt is not None
            and s.state == DeviceState.CUTTING
            and drill >= bt
        ):
            self.t_breakthrough = t
        if self.t_breakthrough is not None and self.t_let_go is None and s.force_est_n < LET_GO_N:
            self.t_let_go = t
        self._feed(t, s.state == DeviceState.CUTTING)

    def _hand(self, t: float, force_n: float) -> None:
        """The hand's peak: the largest mean reading over :data:`HAND_PEAK_WINDOW_S` of armed
        samples (a session armed for less than that: the mean of all its readings)."""
        if self._hand_start_s is None:
            self._hand_start_s = t
        window = self._hand_window
        window.append((t, force_n))
        self._hand_window_sum += force_n
        while window[0][0] <= t - HAND_PEAK_WINDOW_S + 1e-9:
            self._hand_window_sum -= window.popleft()[1]
        mean = self._hand_window_sum / len(window)
        if t - self._hand_start_s >= HAND_PEAK_WINDOW_S - 1e-9:
            self._hand_window_full = True
        if self._hand_window_full:
            self.hand_peak = max(self.hand_peak, mean)
        else:
            self._hand_short_mean = mean

    def _feed(self, t: float, cutting: bool) -> None:
        """Close a feed window every :data:`FEED_WINDOW_S`: it counts when the drill cut
        material all through it (cutting state, ``S0 > 0`` at the front) and advanced."""
        front = self.deepest_mm
        self._win_cut = self._win_cut and cutting and self._s0_at(front) > 0.0
        if self._win is None:
            self._win, self._win_cut = (t, front), cutting
            return
        t0, front0 = self._win
        if t - t0 < FEED_WINDOW_S - 1e-9:
            return
        feed = (front - front0) / (t - t0)
        if self._win_cut and feed > 0.0:
            self._feeds += 1
            delta = feed - self._feed_mean
            self._feed_mean += delta / self._feeds
            self._feed_m2 += delta * (feed - self._feed_mean)
        self._win, self._win_cut = (t, front), cutting

    def result(self) -> Assessment:
        """The assessment of everything added so far."""
        ctx = self.context
        over = self.deepest_mm - ctx.max_safe_depth_mm
        breach = over > DEPTH_TOLERANCE_MM
        clearance = ctx.clearance_at_mm(self.deepest_mm)
        cv = None
        if self._feeds >= 2 and self._feed_mean > 0.0:
            cv = round(math.sqrt(self._feed_m2 / self._feeds) / self._feed_mean, 4)
        reaction = None
        if self.t_breakthrough is not None:
            end = self.t_let_go if self.t_let_go is not None else self.last_t
            reaction = round(1e3 * (end - self.t_breakthrough), 1)
        fields: dict[str, Any] = {
            "depth_error_mm": round(self.deepest_mm - ctx.planned_depth_mm, 4),
            "overshoot_mm": round(over, 4) if breach else 0.0,
            "breach": breach,
            "time_in_margin_s": round(self.time_in_margin_s, 4),
            "canal_entered": clearance is not None and clearance < 0.0,
            "peak_hand_force_n": round(
                self.hand_peak if self._hand_window_full else self._hand_short_mean, 3
            ),
            "mean_hand_force_n": round(self.hand_sum / max(self.hand_count, 1), 3),
            "time_to_planned_s": None if self.t_goal is None else round(self.t_goal, 4),
            "feed_cv": cv,
            "reaction_ms": reaction,
            "wall_contacts": self.wall_contacts,
            "peak_wall_force_n": round(self.wall_peak, 3),
        }
        return Assessment(**fields, score=score_of(fields))
