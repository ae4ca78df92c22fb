"""``ctdrill suggest``, headless: candidate axes around a planned one, scored, safety first.

:func:`suggest` makes the candidates (:mod:`ctdrill.app.search.candidates`; candidate 0 is the
planned axis), evaluates them all in one batch
(:func:`ctdrill.engine.batch.evaluate_batch`: the answers of ``plan_path``), scores
their bone engagement (:mod:`ctdrill.app.search.score`) and ranks them under the **hard
rule**: a candidate is feasible only when its drill reaches the planned depth, i.e. the
batch's stop reason is ``planned_depth`` (the max safe depth keeps every landmark's margin
down to the planned depth and the lip stays in the scanned volume), and nothing refused it
(gaps, padding, an entry outside the scan) and its line met the bone surface. Feasible rows
come first, by score (highest first), then the rest by score; ties keep the candidate order.
:func:`ctdrill.app.search.suggest_write.write_suggestion` writes the outputs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from ctdrill.app.search.candidates import (
    SURFACE_SEARCH_MM,
    Candidates,
    SearchSpace,
    make_candidates,
)
from ctdrill.app.search.score import Objective, Scores, combine, score_rows
from ctdrill.imaging.plan.types import Plan, series_uid_hash
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration


class BatchLike(Protocol):
    """What :func:`suggest` reads of a ``BatchResult`` (``ctdrill.engine.batch``)."""

    @property
    def depth_mm(self) -> np.ndarray: ...
    @property
    def disc_hu(self) -> np.ndarray: ...
    @property
    def max_safe_depth_mm(self) -> np.ndarray: ...
    @property
    def max_safe_depth_capped(self) -> np.ndarray: ...
    @property
    def binding_landmark(self) -> np.ndarray: ...
    @property
    def plan_clearance_mm(self) -> np.ndarray: ...
    @property
    def out_of_volume_depth_mm(self) -> np.ndarray: ...
    @property
    def stop_reason(self) -> np.ndarray: ...
    @property
    def refusal(self) -> tuple[str | None, ...]: ...


#: ``evaluate(volume, plan, entries_lps, targets_lps, calibration, interpolate_gaps=...)``.
Evaluator = Callable[..., BatchLike]


@dataclass(frozen=True, eq=False)
class Suggestion:
    """Every candidate, its score terms, its safety and the ranking.

    Attributes
    ----------
    plan : the planned trajectory the candidates surround (candidate 0).
    space, objective : the settings.
    candidates : the axes.
    scores : score terms (NaN where not evaluated).
    max_safe_depth_mm, max_safe_depth_capped, min_clearance_mm : (N,) from the batch (NaN /
        False where not evaluated; ``min_clearance_mm`` NaN without landmarks).
    binding : (N,) name of the landmark whose margin binds ("" when none binds).
    stop_reason : (N,) ``planned_depth`` | ``margin`` | ``out_of_volume`` | "" (not evaluated).
    feasible : (N,) bool, the hard rule.
    reason : (N,) why a row is not feasible ("" when it is).
    order : (N,) candidate indices, best first (feasible first).
    series_uid : the SeriesInstanceUID of the CT (recorded hashed in ``best.plan.json``).
    evaluate_s, total_s : wall time of the batch evaluation and of the whole search, s.
    notes : what the user must know (one line each).
    """

    plan: Plan
    space: SearchSpace
    objective: Objective
    candidates: Candidates
    scores: Scores
    max_safe_depth_mm: np.ndarray
    max_safe_depth_capped: np.ndarray
    min_clearance_mm: np.ndarray
    binding: tuple[str, ...]
    stop_reason: tuple[str, ...]
    feasible: np.ndarray
    reason: tuple[str, ...]
    order: np.ndarray
    series_uid: str
    evaluate_s: float
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


def _default_evaluator() -> Evaluator:
    from ctdrill.engine.batch import evaluate_batch

    return evaluate_batch


#: Candidates evaluated per batch call: bounds memory (a row is about 50 kB of arrays).
CHUNK = 4096


@dataclass
class _Rows:
    """Per-candidate answers, filled chunk by chunk."""

    body: np.ndarray
    crest: np.ndarray
    apex: np.ndarray
    msd: np.ndarray
    capped: np.ndarray
    clear: np.ndarray
    feasible: np.ndarray
    binding: list[str]
    stop: list[str]
    reason: list[str]

    @classmethod
    def empty(cls, n: int) -> _Rows:
        def nan() -> np.ndarray:
            return np.full(n, np.nan)

        return cls(
            nan(), nan(), nan(), nan(), np.zeros(n, dtype=bool), nan(),
            np.zeros(n, dtype=bool), [""] * n, [""] * n, [""] * n,
        )  # fmt: skip

    def take(self, rows: np.ndarray, batch: BatchLike, plan: Plan, objective: Objective) -> None:
        """Copy ``batch`` (the candidates ``rows``, in order) in."""
        sc = score_rows(batch.depth_mm, batch.disc_hu, plan.planned_depth_mm, objective)
        self.body[rows], self.crest[rows], self.apex[rows] = (
            sc.body_hu, sc.crest_cortical, sc.apex_cortical
        )  # fmt: skip
        self.msd[rows] = batch.max_safe_depth_mm
        self.capped[rows] = batch.max_safe_depth_capped
        self.clear[rows] = batch.plan_clearance_mm
        for k, i in enumerate(rows):
            refusal = batch.refusal[k]
            if refusal is not None:
                self.reason[i] = f"refused: {refusal}"
                continue
            j = int(batch.binding_landmark[k])
            if 0 <= j < len(plan.landmarks) and not self.capped[i]:
                self.binding[i] = plan.landmarks[j].name
            stop = self.stop[i] = str(batch.stop_reason[k])
            if stop == "planned_depth":
                self.feasible[i] = True
            elif stop == "margin":
                self.reason[i] = (
                    f"margin to {self.binding[i]!r}: max safe depth {self.msd[i]:.3f} mm"
                )
            elif stop == "out_of_volume":
                oov = float(batch.out_of_volume_depth_mm[k])
                self.reason[i] = f"leaves the CT at {oov:.3f} mm"
            else:
                self.reason[i] = f"stops on {stop!r}"


def suggest(
    volume: CTVolume,
    plan: Plan,
    calibration: Calibration,
    space: SearchSpace | None = None,
    objective: Objective | None = None,
    *,
    interpolate_gaps: bool = False,
    evaluate: Evaluator | None = None,
) -> Suggestion:
    """Search the axes around ``plan`` (module docstring).

    Parameters
    ----------
    volume : the CT (LPS).
    plan : the planned trajectory, its drill, landmarks and margins.
    calibration : the force-law set (the batch computes forces; the score uses HU only).
    space, objective : the search space and the objective (defaults: the command's).
    interpolate_gaps : passed to the evaluation (interpolate across slice gaps instead of
        refusing the candidates that cross one).
    evaluate : the batch evaluator (default ``evaluate_batch``).

    Raises
    ------
    PathInputError
        A volume no trajectory can use (a single slice, values not HU).
    """
    t0 = time.perf_counter()
    space = space or SearchSpace()
    objective = objective or Objective()
    evaluator = evaluate or _default_evaluator()
    # A sequence's final drill makes the final osteotomy: it is what the axis is checked and
    # scored with (the score reads HU, not forces); best.plan.json keeps the whole sequence.
    final = plan.for_drill(len(plan.drills) - 1) if plan.earlier_drills else plan
    cands = make_candidates(volume, final, space)
    n = cands.size
    out = _Rows.empty(n)
    for i in np.flatnonzero(cands.no_surface):
        out.reason[i] = f"no bone surface on its line within {SURFACE_SEARCH_MM:g} mm of the anchor"
    rows = np.flatnonzero(~cands.no_surface)
    t1 = time.perf_counter()
    for lo in range(0, rows.size, CHUNK):
        part = rows[lo : lo + CHUNK]
        batch = evaluator(
            volume,
            final,
            cands.entries_lps[part],
            cands.targets_lps[part],
            calibration,
            interpolate_gaps=interpolate_gaps,
        )
        out.take(part, batch, final, objective)
    evaluate_s = time.perf_counter() - t1
    scores = combine(out.body, out.crest, out.apex, objective)
    feasible = out.feasible
    key = np.where(np.isfinite(scores.total), -scores.total, np.inf)
    order = np.lexsort((np.arange(n), key, ~feasible))
    notes = _notes(plan, cands, feasible)
    return Suggestion(
        plan=plan,
        space=space,
        objective=objective,
        candidates=cands,
        scores=scores,
        max_safe_depth_mm=out.msd,
        max_safe_depth_capped=out.capped,
        min_clearance_mm=out.clear,
        binding=tuple(out.binding),
        stop_reason=tuple(out.stop),
        feasible=feasible,
        reason=tuple(out.reason),
        order=order,
        series_uid=volume.info.series_uid,
        evaluate_s=evaluate_s,
        total_s=time.perf_counter() - t0,
        notes=notes,
    )


def _notes(plan: Plan, cands: Candidates, feasible: np.ndarray) -> tuple[str, ...]:
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
    if plan.earlier_drills:
        sizes = ", ".join(f"{d.diameter_mm:g}" for d in plan.drills)
        out.append(
            f"plan {plan.name!r} drills a sequence ({sizes} mm): candidates are checked and "
            f"scored with the final {plan.drill.diameter_mm:g} mm drill alone; the earlier "
            "drills' own stops are not checked here (ctdrill export on best.plan.json checks "
            "each drill)"
        )
    missing = int(np.count_nonzero(cands.no_surface))
    if missing:
        out.append(
            f"{missing} of {cands.size} candidate lines meet no bone surface within "
            f"{SURFACE_SEARCH_MM:g} mm of their anchor: not evaluated, not feasible"
        )
    if not plan.landmarks:
        out.append(
            f"plan {plan.name!r} has no landmark: feasibility checks the planned depth and the "
            "volume only, no safety margin"
        )
    if not feasible.any():
        out.append(
            f"no feasible candidate: none of the {cands.size} axes reaches the planned depth "
            f"{plan.planned_depth_mm:.3f} mm keeping every landmark's margin; "
            "best.plan.json is not written"
        )
    return tuple(out)
