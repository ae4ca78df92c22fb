"""``ctdrill suggest``, headless: candidate axes around a planned one, scored, safety first.

:func:`suggest` makes the candidates (:mod:`ctdrill.app.search.candidates`; candidate 0 is the
planned axis) and ranks them in two stages:

1. **Cheap, for every candidate.** One batch evaluation of the final drill drilled as it is
   for the implant (:meth:`~ctdrill.imaging.plan.types.Plan.drilled`, tip beyond the apex;
   :func:`ctdrill.engine.batch.evaluate_batch`, the answers of ``plan_path``): its stop
   reason must be ``planned_depth`` (the drill keeps every landmark's margin down to its
   planned depth, its lip stays in the scanned volume, nothing refused the path: gaps,
   padding, an entry outside the scan) and its line met the bone surface. And the shell HU
   around the body (:mod:`ctdrill.app.search.shell`), read once for all: the score
   (:mod:`ctdrill.app.search.score`) and the flags of a likely perforation or thin wall.
2. **Exact, for the best-ranked.** The candidates that passed stage 1 are checked in order
   (the planned axis first, then unflagged first, each by score) with the one feasibility rule
   (:func:`ctdrill.app.search.feasibility.check_candidate`: every drill's and the implant's
   margins, the bone walls), until ``wanted`` feasible ones are found or ``max_checked``
   were checked. Only a checked candidate can be feasible; the others say why not (their
   stage-1 reason, or "not checked").

Feasible rows come first, by score (highest first), then the rest by score; ties keep the
candidate order. :func:`ctdrill.app.search.suggest_write.write_suggestion` writes the outputs.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from ctdrill.app.search.candidates import (
    SURFACE_SEARCH_MM,
    Candidates,
    SearchSpace,
    make_candidates,
)
from ctdrill.app.search.feasibility import check_candidate
from ctdrill.app.search.score import Objective, Scores, ranked_total, score_rows
from ctdrill.app.search.shell import body_profile, sample_shells
from ctdrill.app.search.stages import (
    Checker,
    CheckSettings,
    Evaluator,
    Exact,
    Rows,
)
from ctdrill.imaging.plan.types import Plan, series_uid_hash
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration


@dataclass(frozen=True, eq=False)
class Suggestion:
    """Every candidate, its score terms, its safety and the ranking.

    Attributes
    ----------
    plan : the planned trajectory the candidates surround (candidate 0).
    space, objective, check : the settings.
    body : what the score's shell surrounds (the implant, or the final drill's osteotomy).
    candidates : the axes.
    scores : score terms (NaN where not evaluated).
    max_safe_depth_mm, max_safe_depth_capped, min_clearance_mm : (N,) the final drill's, from
        the batch (NaN / False where not evaluated; ``min_clearance_mm`` NaN without landmarks).
    binding : (N,) name of the landmark whose margin binds ("" when none binds).
    stop_reason : (N,) ``planned_depth`` | ``margin`` | ``out_of_volume`` | "" (not evaluated).
    passed : (N,) bool, stage 1 held (the final drill reaches its planned depth).
    checked : (N,) bool, the exact check ran.
    problems : (N,) the codes the exact check found (``;``-joined; "" when none or not
        checked).
    implant_clearance_mm, min_wall_mm : (N,) from the exact check (NaN when not checked or
        not defined); ``wall_balance`` (N,) how even the walls are
        (:func:`~ctdrill.app.search.score.wall_balance`), added to the ranking.
    feasible : (N,) bool: checked and no problem.
    reason : (N,) why a row is not feasible ("" when it is).
    order : (N,) candidate indices, best first (feasible first).
    series_uid : the SeriesInstanceUID of the CT (recorded hashed in ``best.plan.json``).
    evaluate_s, check_s, total_s : wall time of the batch evaluation, of the exact checks and
        of the whole search, s.
    notes : what the user must know (one line each).
    """

    plan: Plan
    space: SearchSpace
    objective: Objective
    check: CheckSettings
    body: str
    candidates: Candidates
    scores: Scores
    max_safe_depth_mm: np.ndarray
    max_safe_depth_capped: np.ndarray
    min_clearance_mm: np.ndarray
    binding: tuple[str, ...]
    stop_reason: tuple[str, ...]
    passed: np.ndarray
    checked: np.ndarray
    problems: tuple[str, ...]
    implant_clearance_mm: np.ndarray
    min_wall_mm: np.ndarray
    wall_balance: np.ndarray
    feasible: np.ndarray
    reason: tuple[str, ...]
    order: np.ndarray
    series_uid: str
    evaluate_s: float
    check_s: float
    total_s: float
    notes: tuple[str, ...]

    @property
    def best_index(self) -> int | None:
        """The best feasible candidate, or None when none is feasible."""
        first = int(self.order[0])
        return first if bool(self.feasible[first]) else None

    @property
    def n_feasible(self) -> int:
        """Feasible candidates."""
        return int(np.count_nonzero(self.feasible))

    @property
    def n_passed(self) -> int:
        """Candidates that passed stage 1."""
        return int(np.count_nonzero(self.passed))

    @property
    def n_checked(self) -> int:
        """Candidates checked exactly."""
        return int(np.count_nonzero(self.checked))

    def rank_of(self, index: int) -> int:
        """1-based rank of candidate ``index``."""
        return int(np.flatnonzero(self.order == index)[0]) + 1

    def plan_of(self, index: int) -> Plan:
        """The input plan with candidate ``index``'s axis (everything else kept; the series
        the axis was found on recorded)."""
        return replace(
            self.plan,
            entry_lps=self.candidates.entries_lps[index],
            target_lps=self.candidates.targets_lps[index],
            series_uid_sha256=series_uid_hash(self.series_uid),
        )

    def best_plan(self) -> Plan | None:
        """:meth:`plan_of` the best feasible candidate, or None."""
        best = self.best_index
        return None if best is None else self.plan_of(best)


#: Candidates evaluated per batch call: bounds memory (a row is about 50 kB of arrays).
CHUNK = 4096


def _default_evaluator() -> Evaluator:
    from ctdrill.engine.batch import evaluate_batch

    return evaluate_batch


def suggest(
    volume: CTVolume,
    plan: Plan,
    calibration: Calibration,
    space: SearchSpace | None = None,
    objective: Objective | None = None,
    *,
    interpolate_gaps: bool = False,
    evaluate: Evaluator | None = None,
    check: CheckSettings | None = None,
    checker: Checker | None = None,
) -> Suggestion:
    """Search the axes around ``plan`` (module docstring).

    Parameters
    ----------
    volume : the CT (LPS).
    plan : the planned trajectory, its drills, implant, landmarks, margins and ``min_wall_mm``.
    calibration : the force-law set (the batch computes forces; the score uses HU only).
    space, objective : the search space and the objective (defaults: the command's).
    interpolate_gaps : passed to the evaluation (interpolate across slice gaps instead of
        refusing the candidates that cross one).
    evaluate : the batch evaluator (default ``evaluate_batch``).
    check : how far the exact check goes (default :class:`CheckSettings`).
    checker : the feasibility rule (default
        :func:`~ctdrill.app.search.feasibility.check_candidate`).

    Raises
    ------
    PathInputError
        A volume no trajectory can use (a single slice, values not HU).
    """
    t0 = time.perf_counter()
    space = space or SearchSpace()
    objective = objective or Objective()
    check = check or CheckSettings()
    evaluator = evaluate or _default_evaluator()
    checker = checker or check_candidate
    # The axis as drawn (target: the implant's apex) with the final drill, and that drill as
    # it is drilled for the implant (its tip beyond the apex): stage 1 checks the latter.
    drawn = plan.for_drill(len(plan.drills) - 1)
    drilled = drawn.drilled(0)
    cands = make_candidates(volume, drawn, space)
    n = cands.size
    dirs = cands.targets_lps - cands.entries_lps
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    out = Rows.empty(n)
    for i in np.flatnonzero(cands.no_surface):
        out.reason[i] = f"no bone surface on its line within {SURFACE_SEARCH_MM:g} mm of the anchor"
    rows = np.flatnonzero(~cands.no_surface)
    t1 = time.perf_counter()
    for lo in range(0, rows.size, CHUNK):
        part = rows[lo : lo + CHUNK]
        batch = evaluator(
            volume,
            drilled,
            cands.entries_lps[part],
            cands.entries_lps[part] + drilled.planned_depth_mm * dirs[part],
            calibration,
            interpolate_gaps=interpolate_gaps,
            profiles=False,
        )
        out.take(part, batch, drilled)
    evaluate_s = time.perf_counter() - t1
    body = body_profile(drawn)
    shells = sample_shells(
        volume, body, cands.entries_lps[rows], dirs[rows], min_wall_mm=plan.min_wall_mm
    )
    hu = np.full((n, *shells.hu.shape[1:]), np.nan)
    hu[rows] = shells.hu
    flagged = np.zeros(n, dtype=bool)
    if plan.implant is not None:  # no implant, no walls: nothing to flag
        flagged[rows] = shells.likely_perforation | shells.likely_thin_wall
    scores = score_rows(hu, body.s_mm, objective)
    key = np.where(np.isfinite(scores.total), -scores.total, np.inf)
    t2 = time.perf_counter()
    exact = Exact.run(volume, cands, plan, out, key, flagged, check, checker)
    check_s = time.perf_counter() - t2
    ranked = ranked_total(scores.total, exact.balance, objective)
    rank_key = np.where(np.isfinite(ranked), -ranked, np.inf)
    order = np.lexsort((np.arange(n), rank_key, ~exact.feasible))
    notes = _notes(plan, cands, out.passed, exact, check, body.what, drilled.planned_depth_mm)
    return Suggestion(
        plan=plan,
        space=space,
        objective=objective,
        check=check,
        body=body.what,
        candidates=cands,
        scores=scores,
        max_safe_depth_mm=out.msd,
        max_safe_depth_capped=out.capped,
        min_clearance_mm=out.clear,
        binding=tuple(out.binding),
        stop_reason=tuple(out.stop),
        passed=out.passed,
        checked=exact.checked,
        problems=tuple(exact.problems),
        implant_clearance_mm=exact.implant_mm,
        min_wall_mm=exact.wall_mm,
        wall_balance=exact.balance,
        feasible=exact.feasible,
        reason=tuple(out.reason),
        order=order,
        series_uid=volume.info.series_uid,
        evaluate_s=evaluate_s,
        check_s=check_s,
        total_s=time.perf_counter() - t0,
        notes=notes,
    )


def _notes(
    plan: Plan,
    cands: Candidates,
    passed: np.ndarray,
    exact: Exact,
    check: CheckSettings,
    body: str,
    depth_mm: float,
) -> tuple[str, ...]:
    out: list[str] = []
    gap = cands.planned_surface_mm
    if not math.isfinite(gap):
        out.append(
            "the planned axis meets no bone surface within "
            f"{SURFACE_SEARCH_MM:g} mm of its entry; candidate 0 is taken as planned"
        )
    elif abs(gap) > 0.05:
        where = "above" if gap > 0 else "below"
        out.append(
            f"the planned entry lies {abs(gap):.2f} mm {where} the bone surface along its axis; "
            "the other candidates enter on the surface, candidate 0 as planned"
        )
    out.append(f"the score reads the bone around {body}")
    if plan.implant is None:
        out.append(
            f"plan {plan.name!r} places no implant: feasibility checks the drills' margins "
            "only (no implant body, no bone walls)"
        )
    missing = int(np.count_nonzero(cands.no_surface))
    if missing:
        out.append(
            f"{missing} of {cands.size} candidate lines meet no bone surface within "
            f"{SURFACE_SEARCH_MM:g} mm of their anchor: not evaluated, not feasible"
        )
    if not plan.landmarks:
        walls = "" if plan.implant is None else " and the bone walls"
        out.append(
            f"plan {plan.name!r} has no landmark: feasibility checks the planned depth, the "
            f"volume{walls}, no safety margin"
        )
    n_passed, n_checked = int(passed.sum()), int(exact.checked.sum())
    n_feasible = int(exact.feasible.sum())
    stopped = (
        f"stopped at {check.wanted} feasible"
        if n_feasible >= check.wanted
        else f"stopped at the limit of {check.max_checked} checks"
        if n_checked >= check.max_checked
        else "all checked"
    )
    out.append(
        f"exact check (every drill's and the implant's margins, bone walls) of the "
        f"{n_passed} candidates whose final drill reaches its planned depth, best-ranked "
        f"first: {n_checked} checked, {n_feasible} feasible ({stopped}); the rest are not "
        "checked and not feasible"
    )
    if not n_passed:
        out.append(
            f"no feasible candidate: none of the {cands.size} axes reaches the planned depth "
            f"{depth_mm:.3f} mm keeping every landmark's margin; best.plan.json is not written"
        )
    elif not n_feasible:
        codes = (c for i in np.flatnonzero(exact.checked) for c in exact.problems[i].split(";"))
        found = ", ".join(f"{code} {k}" for code, k in Counter(codes).most_common())
        out.append(
            f"no feasible candidate: none of the {n_checked} checked axes keeps every margin "
            f"and bone wall ({found}); best.plan.json is not written"
        )
    return tuple(out)
