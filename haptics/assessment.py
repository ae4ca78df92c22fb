"""How a rehearsal went: the ``assessment`` of ``summary.json`` (docs/rehearse.md).

:class:`Assessor` reads a session's trace row by row (constant memory, any length) and gives an
:class:`Assessment`, whose fields are fixed (:data:`ASSESSMENT_FIELDS`). It reads the rows as
``session.csv`` holds them (:func:`ctdrill.haptics.session.csv_cells`: the digits written),
whether live from telemetry (:meth:`Assessor.add`) or from the file (:meth:`Assessor.add_cells`),
so the file recomputes the assessment exactly. The score is
:func:`ctdrill.haptics.score.score_of`, a pure function of the fields.

Depths are the drill's (``drill_mm``: it never passes the device's stop); the hand force is the
device's reading of the hand (``hand_force_n``, telemetry ``force_est_n``); the breakthrough is
the table's decisive one (:func:`ctdrill.haptics.hands.decisive_breakthrough_mm`). Nothing the
score reads changes after the session's last cutting event: resting, retracting, waiting and
holding a constant push against the wall change nothing (a contact's pressing counts up to
:data:`~ctdrill.haptics.score.WALL_GRACE_S` plus
:data:`~ctdrill.haptics.score.WALL_PRESS_SATURATE_S`; a hand that never let go after the
breakthrough is charged at least :data:`~ctdrill.haptics.score.REACTION_SCALE_MS`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from typing import Any

from ctdrill.haptics.assessment_fields import (
    ASSESSMENT_FIELDS,
    BOOL_FIELDS,
    INT_FIELDS,
    NULLABLE_FIELDS,
    Assessment,
    AssessmentContext,
    combine_assessments,
)
from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.hands import decisive_breakthrough_mm
from ctdrill.haptics.plant import COULOMB_N
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.score import (
    DEPTH_SCALE_MM,
    REACTION_SCALE_MS,
    WALL_GRACE_S,
    WALL_PRESS_SATURATE_S,
    score_of,
    score_terms,
)
from ctdrill.haptics.session import STATE_NAMES, csv_cells, sample_row

__all__ = [
    "ASSESSMENT_FIELDS",
    "BOOL_FIELDS",
    "INT_FIELDS",
    "NULLABLE_FIELDS",
    "Assessment",
    "AssessmentContext",
    "Assessor",
    "combine_assessments",
    "score_of",
    "score_terms",
]

#: A drill depth counts as beyond the max safe depth (or at a goal) past this tolerance, mm:
#: the device holds its stop in float32 (a 10.8 mm stop reads 10.7999992 mm) and its encoder
#: counts 0.1 um.
DEPTH_TOLERANCE_MM = 1e-3
#: The drill's front advanced (a cutting event) when it passed its deepest by more than this,
#: mm (``session.csv`` holds 10 nm).
CUT_EVENT_MM = 1e-5
#: The hand has let go once the device reads it below this force, N (the master's Coulomb
#: friction: less does not move it); it pushes at this force or more.
LET_GO_N = COULOMB_N
#: The master is in contact with the stop's wall when beyond the drill by more than this, mm
#: (stopped, the hand pushing) ...
WALL_CONTACT_MM = 1e-4
#: ... and the contact lasts until the hand lets go, the drill leaves the stop or the handle
#: comes back more than this short of the drill, mm (a bounce off the wall is one contact).
WALL_RELEASE_MM = 0.5
#: The feed is measured over windows of this much session time, s.
FEED_WINDOW_S = 0.1
#: The hand's peak force is the largest mean of the device's reading over this much session
#: time, s: a person's push (voluntary force control reaches about 10 Hz), not the reaction
#: observer's few-millisecond transients where the push steps or the handle meets the wall
#: (a steady 12 N push reads up to 16 N for a millisecond at the stop). The hand's steadiness
#: (``hand_force_cv``) is measured on the same means.
HAND_PEAK_WINDOW_S = 0.05
#: A display that showed a sample later than this after its time lagged: the session is
#: flagged (``display_lagged``) and its reaction not scored, ms.
DISPLAY_LAG_LIMIT_MS = 100.0
#: A contact's pressing counts up to this, s; then the contact is saturated: the hand's peak and
#: the handle's overrun are not measured again until it lets go (:meth:`Assessor._saturated`).
_PRESS_CAP_S = WALL_GRACE_S + WALL_PRESS_SATURATE_S


class _Welford:
    """Running mean and variance."""

    def __init__(self) -> None:
        self.n = 0
        self.mean = 0.0
        self.m2 = 0.0

    def add(self, x: float) -> None:
        self.n += 1
        delta = x - self.mean
        self.mean += delta / self.n
        self.m2 += delta * (x - self.mean)

    def cv(self) -> float | None:
        if self.n < 2 or self.mean <= 0.0:
            return None
        return round(math.sqrt(self.m2 / self.n) / self.mean, 4)


_STATE_OF_NAME = {name: code for code, name in STATE_NAMES.items()}
_CUTTING, _STOPPED = _STATE_OF_NAME["cutting"], _STATE_OF_NAME["stopped"]


class Assessor:
    """Reads a session's trace (:meth:`add` for telemetry, :meth:`add_cells` for
    ``session.csv`` rows) and assesses it (:meth:`result`). Times are session times (from the
    first sample); ``display`` (optional) is when the window showed what: :meth:`shown`."""

    def __init__(self, context: AssessmentContext, table: ProfileTable) -> None:
        self.context = context
        self.table = table
        self._step_mm = float(table.depth_step_mm)
        self._s0 = [float(v) for v in table.s0_n]
        self.breakthrough_mm = decisive_breakthrough_mm(table)
        self.t0: float | None = None
        self.last_t = 0.0
        self.deepest_mm = 0.0
        self.t_goal: float | None = None
        self._margin_s = 0.0
        self._margin_pending_s = 0.0
        self.hand_peak = 0.0
        self._hand_window: deque[tuple[float, float, bool]] = deque()
        self._hand_window_sum = 0.0
        self._hand_window_idle = 0  # samples in the window not spent cutting
        self._hand_window_full = False
        self._hand_start_s: float | None = None
        self._hand_short_mean = 0.0
        self._hand_mean = _Welford()
        self._hand_steady = _Welford()
        self.wall_contacts = 0
        self.wall_peak = 0.0
        self.wall_press_s = 0.0
        self.wall_overrun_mm = 0.0
        self._in_contact = False
        self._contact_press_s = 0.0
        self._last_cut_s = 0.0
        self.t_breakthrough: float | None = None
        self._drill_at_breakthrough = 0.0
        self.t_let_go: float | None = None
        self._win: tuple[float, float] | None = None
        self._win_cut = True
        self._feed = _Welford()
        self._shown: list[tuple[float, float]] = []

    def _s0_at(self, depth_mm: float) -> float:
        """``S0`` at ``depth_mm``, linear between rows, 0 outside the table (as ``np.interp``
        with ``left = right = 0``; a Python float per row: this runs for every sample)."""
        x = depth_mm / self._step_mm
        last = len(self._s0) - 1
        if x < 0.0 or x > last:
            return 0.0
        i = min(int(x), last - 1) if last > 0 else 0
        if last == 0:
            return self._s0[0]
        w = x - i
        return self._s0[i] * (1.0 - w) + self._s0[i + 1] * w

    def add(self, samples: list[TelemetrySample]) -> None:
        """One block of telemetry, oldest first (read as ``session.csv`` writes it)."""
        for s in samples:
            if self.t0 is None:
                self.t0 = s.time_s
            self.add_cells(csv_cells(sample_row(s.time_s - self.t0, s)))

    def add_cells(self, cells: Sequence[str]) -> None:
        """One ``session.csv`` row's cells (:data:`ctdrill.haptics.session.SESSION_COLUMNS`).

        Raises
        ------
        ValueError
            A cell that is not a finite number, or a state that is not a device state.
        """
        t, master, drill, force = (float(c) for c in cells[:4])
        hand = float(cells[5])
        if not all(math.isfinite(v) for v in (t, master, drill, force, hand)):
            raise ValueError("a value is not a finite number")
        state = _STATE_OF_NAME.get(cells[4])
        if state is None:
            raise ValueError(f"state {cells[4]!r} is not one of {', '.join(_STATE_OF_NAME)}")
        self._add(t, master, drill, force, state, hand)

    def shown(self, sample_t_s: float, shown_at_s: float) -> None:
        """The window showed the sample of session time ``sample_t_s`` at session time
        ``shown_at_s`` (in order): the reaction is timed from when the breakthrough was shown."""
        self._shown.append((sample_t_s, shown_at_s))

    def _add(
        self, t: float, master: float, drill: float, force: float, state: int, hand: float
    ) -> None:
        dt = max(t - self.last_t, 0.0)
        self.last_t = t
        ctx = self.context
        cut = drill > self.deepest_mm + CUT_EVENT_MM
        if drill > self.deepest_mm:
            self.deepest_mm = drill
        if self.t_goal is None and drill >= ctx.goal_depth_mm - DEPTH_TOLERANCE_MM:
            self.t_goal = t
        if drill > ctx.max_safe_depth_mm + DEPTH_TOLERANCE_MM:
            self._margin_pending_s += dt
        if cut:  # time in the margin counts up to the last cutting event
            self._last_cut_s = t
            self._margin_s += self._margin_pending_s
            self._margin_pending_s = 0.0
        pushing = hand >= LET_GO_N
        armed = state in (_CUTTING, _STOPPED)
        cutting_front = state == _CUTTING and pushing and self._s0_at(self.deepest_mm) > 0.0
        held = False  # the hand's mean over the peak window pushes (a 1 ms blip does not)
        if armed:
            held = self._hand(t, hand, cutting_front, self._saturated()) >= LET_GO_N
            if pushing:
                self._hand_mean.add(hand)
        self._wall(dt, master, drill, force, state, held, pushing)
        bt = self.breakthrough_mm
        if self.t_breakthrough is None and bt is not None and state == _CUTTING and drill >= bt:
            self.t_breakthrough = t
            self._drill_at_breakthrough = drill
        if self.t_breakthrough is not None and self.t_let_go is None and not pushing:
            self.t_let_go = t
        self._feed_window(t, state == _CUTTING, cut)

    def _wall(
        self,
        dt: float,
        master: float,
        drill: float,
        force: float,
        state: int,
        pushing: bool,
        pressing: bool,
    ) -> None:
        """Contacts with the stop's wall: stopped, the handle beyond the drill, the hand
        pushing (``pushing``: its mean over :data:`HAND_PEAK_WINDOW_S`, so the release
        damper's millisecond blips after a release are not a new contact); how long it pressed
        (``pressing``: the reading itself at 1 N or more, so the mean's fall after a release
        adds nothing), each contact up to :data:`WALL_GRACE_S` + :data:`WALL_PRESS_SATURATE_S`
        (a hand still pressing then has shown it will not let go within a reaction: pressing
        longer is waiting, and the session's length changes nothing), and how far the handle
        sank past the drill."""
        if state == _STOPPED:
            self.wall_peak = max(self.wall_peak, force)
        held = state == _STOPPED and pushing
        add = 0.0
        if self._in_contact:
            contact = held and master > drill - WALL_RELEASE_MM
        else:
            contact = held and master > drill + WALL_CONTACT_MM
        if contact:
            if not self._in_contact:
                self.wall_contacts += 1
                self._contact_press_s = 0.0
            elif pressing:
                add = min(dt, max(_PRESS_CAP_S - self._contact_press_s, 0.0))
                self._contact_press_s += add
                self.wall_press_s += add
            if pressing and (add > 0.0 or self._contact_press_s == 0.0):
                self.wall_overrun_mm = max(self.wall_overrun_mm, master - drill, 0.0)
        self._in_contact = contact

    def _saturated(self) -> bool:
        """In a contact with the wall whose pressing has saturated: the hand has shown it will
        not let go, and how it goes on leaning (harder, deeper) is not measured again."""
        return self._in_contact and self._contact_press_s >= _PRESS_CAP_S

    def _hand(self, t: float, force_n: float, cutting: bool, saturated: bool) -> float:
        """The hand's peak: the largest mean reading over :data:`HAND_PEAK_WINDOW_S` of armed
        samples (a session armed for less than that: the mean of all its readings); its
        steadiness: the spread of those means over windows spent cutting. The peak is not
        taken while ``saturated`` (:meth:`_saturated`). Returns the current window's mean, N."""
        if self._hand_start_s is None:
            self._hand_start_s = t
        window = self._hand_window
        window.append((t, force_n, cutting))
        self._hand_window_sum += force_n
        self._hand_window_idle += not cutting
        while window[0][0] <= t - HAND_PEAK_WINDOW_S + 1e-9:
            _, old, old_cutting = window.popleft()
            self._hand_window_sum -= old
            self._hand_window_idle -= not old_cutting
        mean = self._hand_window_sum / len(window)
        if t - self._hand_start_s >= HAND_PEAK_WINDOW_S - 1e-9:
            self._hand_window_full = True
        if self._hand_window_full and not saturated:
            self.hand_peak = max(self.hand_peak, mean)
            if self._hand_window_idle == 0:
                self._hand_steady.add(mean)
        else:
            self._hand_short_mean = mean
        return mean

    def _feed_window(self, t: float, cutting: bool, cut: bool) -> None:
        """Close a feed window every :data:`FEED_WINDOW_S`, on a cutting event (a window open
        at the last cut never closes: what follows it changes nothing): it counts when the
        drill cut material all through it (cutting state, ``S0 > 0`` at the front) and
        advanced."""
        front = self.deepest_mm
        self._win_cut = self._win_cut and cutting and self._s0_at(front) > 0.0
        if self._win is None:
            self._win, self._win_cut = (t, front), cutting
            return
        t0, front0 = self._win
        if t - t0 < FEED_WINDOW_S - 1e-9 or not cut:
            return
        feed = (front - front0) / (t - t0)
        if self._win_cut and feed > 0.0:
            self._feed.add(feed)
        self._win, self._win_cut = (t, front), cutting

    def _display(self) -> tuple[float | None, float | None]:
        """``(largest display lag ms, when the breakthrough was shown s)``; None without a
        display."""
        if not self._shown:
            return None, None
        lag = max(shown - sample for sample, shown in self._shown)
        seen = None
        if self.t_breakthrough is not None:
            after = [shown for sample, shown in self._shown if sample >= self.t_breakthrough]
            seen = min(after) if after else None
        return round(1e3 * max(lag, 0.0), 1), seen

    def result(self) -> Assessment:
        """The assessment of everything added so far."""
        ctx = self.context
        over = self.deepest_mm - ctx.max_safe_depth_mm
        breach = over > DEPTH_TOLERANCE_MM
        clearance = ctx.clearance_at_mm(self.deepest_mm)
        lag_ms, seen_s = self._display()
        reaction = None
        if self.t_breakthrough is not None:
            start = self.t_breakthrough if seen_s is None else seen_s
            if self.t_let_go is not None:
                reaction = round(1e3 * max(self.t_let_go - start, 0.0), 1)
            else:  # never let go: the whole reaction term, whatever the session's length
                late_ms = 1e3 * max(self._last_cut_s - start, 0.0)
                reaction = round(max(late_ms, REACTION_SCALE_MS), 1)
        plunge = 0.0
        if self.t_breakthrough is not None:
            plunge = self.deepest_mm - self._drill_at_breakthrough
        goal = ctx.goal_depth_mm
        peak = self.hand_peak if self._hand_window_full else self._hand_short_mean
        fields: dict[str, Any] = {
            "depth_error_mm": round(self.deepest_mm - goal, 4),
            "overshoot_mm": round(over, 4) if breach else 0.0,
            "breach": breach,
            "time_in_margin_s": round(self._margin_s, 4),
            "canal_entered": clearance is not None and clearance < 0.0,
            "peak_hand_force_n": round(peak, 3),
            "mean_hand_force_n": round(self._hand_mean.mean, 3),
            "time_to_planned_s": None if self.t_goal is None else round(self.t_goal, 4),
            "feed_cv": self._feed.cv(),
            "reaction_ms": reaction,
            "wall_contacts": self.wall_contacts,
            "peak_wall_force_n": round(self.wall_peak, 3),
            "goal_depth_mm": round(goal, 4),
            "attempted": breach or self.deepest_mm >= goal - DEPTH_SCALE_MM - DEPTH_TOLERANCE_MM,
            "hand_force_cv": self._hand_steady.cv(),
            "plunge_mm": round(max(plunge, 0.0), 4),
            "wall_press_s": round(self.wall_press_s, 4),
            "wall_overrun_mm": round(self.wall_overrun_mm, 4),
            "display_lag_ms": lag_ms,
            "display_lagged": lag_ms is not None and lag_ms > DISPLAY_LAG_LIMIT_MS,
        }
        return Assessment(**fields, score=score_of(fields))
