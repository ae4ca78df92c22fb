"""The two stages of ``ctdrill suggest`` (:mod:`ctdrill.app.search.suggest`): what stage 1
keeps of the batch evaluation per candidate, and stage 2, the exact check of the best-ranked."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from ctdrill.app.search.candidates import Candidates
from ctdrill.app.search.feasibility import Feasibility
from ctdrill.app.search.score import wall_balance
from ctdrill.engine.stop import StopReason
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume

#: The exact check stops once this many candidates are feasible (the window lists the five
#: best distinct ones) ...
FEASIBLE_WANTED = 20
#: ... or once this many were checked (each check costs tens of milliseconds: the walls).
MAX_CHECKED = 50


class BatchLike(Protocol):
    """What :func:`suggest` reads of a ``BatchResult`` (``ctdrill.engine.batch``)."""

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


#: ``evaluate(volume, plan, entries_lps, targets_lps, calibration, interpolate_gaps=...,
#: profiles=False)`` (the stops only: :func:`ctdrill.engine.batch.evaluate_batch`).
Evaluator = Callable[..., BatchLike]
#: ``check(volume, candidate_plan) -> Feasibility`` (default :func:`check_candidate`).
Checker = Callable[[CTVolume, Plan], Feasibility]


@dataclass(frozen=True)
class CheckSettings:
    """How far the exact check goes (module docstring, stage 2).

    Attributes
    ----------
    wanted : stop once this many candidates are feasible.
    max_checked : stop once this many were checked.
    """

    wanted: int = FEASIBLE_WANTED
    max_checked: int = MAX_CHECKED

    def __post_init__(self) -> None:
        if not (self.wanted >= 1 and self.max_checked >= 1):
            raise ValueError("check settings: wanted and max_checked must be >= 1")


@dataclass
class Rows:
    """Per-candidate answers, filled chunk by chunk."""

    msd: np.ndarray
    capped: np.ndarray
    clear: np.ndarray
    passed: np.ndarray
    binding: list[str]
    stop: list[str]
    reason: list[str]

    @classmethod
    def empty(cls, n: int) -> Rows:
        nan = np.full(n, np.nan)
        no = np.zeros(n, dtype=bool)
        return cls(nan.copy(), no.copy(), nan.copy(), no.copy(), [""] * n, [""] * n, [""] * n)

    def take(self, rows: np.ndarray, batch: BatchLike, plan: Plan) -> None:
        """Copy ``batch`` (the candidates ``rows``, in order; ``plan`` the drilled final
        drill) in."""
        self.msd[rows] = batch.max_safe_depth_mm
        self.capped[rows] = batch.max_safe_depth_capped
        self.clear[rows] = batch.plan_clearance_mm
        what = f"final drill ({plan.drill.diameter_mm:g} mm, to {plan.planned_depth_mm:.2f} mm)"
        for k, i in enumerate(rows):
            refusal = batch.refusal[k]
            if refusal is not None:
                self.reason[i] = f"refused: {refusal}"
                continue
            j = int(batch.binding_landmark[k])
            if 0 <= j < len(plan.landmarks) and not self.capped[i]:
                self.binding[i] = plan.landmarks[j].name
            stop = self.stop[i] = str(batch.stop_reason[k])
            if stop == StopReason.PLANNED_DEPTH:
                self.passed[i] = True
            elif stop == StopReason.MARGIN:
                self.reason[i] = (
                    f"{what}: margin to {self.binding[i]!r}: max safe depth {self.msd[i]:.3f} mm"
                )
            elif stop == StopReason.OUT_OF_VOLUME:
                oov = float(batch.out_of_volume_depth_mm[k])
                self.reason[i] = f"{what} leaves the CT at {oov:.3f} mm"
            else:
                self.reason[i] = f"{what} stops on {stop!r}"


@dataclass
class Exact:
    """Stage 2's answers (module docstring)."""

    checked: np.ndarray
    feasible: np.ndarray
    problems: list[str]
    implant_mm: np.ndarray
    wall_mm: np.ndarray
    balance: np.ndarray

    @classmethod
    def run(
        cls,
        volume: CTVolume,
        cands: Candidates,
        plan: Plan,
        rows: Rows,
        key: np.ndarray,
        flagged: np.ndarray,
        check: CheckSettings,
        checker: Checker,
    ) -> Exact:
        """Check the stage-1 survivors in order (the planned axis, candidate 0, first; then
        unflagged first, each by score); fill in ``rows.reason`` for every row not
        feasible."""
        n = cands.size
        nan = np.full(n, np.nan)
        ex = cls(np.zeros(n, bool), np.zeros(n, bool), [""] * n, nan.copy(), nan.copy(), nan.copy())
        queue = np.lexsort((np.arange(n), key, flagged, ~rows.passed))[: rows.passed.sum()]
        if rows.passed[0]:  # the planned axis first: its verdict is always shown
            queue = np.concatenate([[0], queue[queue != 0]])
        for i in queue:
            if ex.feasible.sum() >= check.wanted or ex.checked.sum() >= check.max_checked:
                break
            axis = replace(plan, entry_lps=cands.entries_lps[i], target_lps=cands.targets_lps[i])
            verdict = checker(volume, axis)
            ex.checked[i] = True
            ex.feasible[i] = verdict.feasible
            ex.problems[i] = ";".join(verdict.codes)
            ex.implant_mm[i] = _nan(verdict.implant_clearance_mm)
            ex.wall_mm[i] = _nan(verdict.min_wall_mm)
            ex.balance[i] = wall_balance(verdict.walls)
            if verdict.problems:
                rows.reason[i] = "; ".join(f"{w.code}: {w.message}" for w in verdict.problems)
        for i in np.flatnonzero(rows.passed & ~ex.checked):
            rows.reason[i] = "not checked (implant, every drill, bone walls): ranked below the " + (
                f"{check.wanted} feasible found" if ex.feasible.sum() >= check.wanted
                else f"{check.max_checked} checked"
            )  # fmt: skip
        return ex


def _nan(value: float | None) -> float:
    return math.nan if value is None else float(value)
