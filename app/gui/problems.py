"""What the window says is wrong with a trajectory, headless: the planned clearances of the
implant and of the osteotomy (the landmark table), the plan problems (the banner) and whether
the implant offends (drawn red in every view).

- **Planned clearance of the osteotomy** (the plan's verdict, :mod:`ctdrill.engine.verdict`,
  computed once with the banner's problems and ``suggest``'s feasibility): every drill of the
  plan as it is drilled for the implant (:meth:`~ctdrill.imaging.plan.types.Plan.drilled`:
  its full diameter to the apex, its tip beyond by its own tip length), measured at its
  planned depth; per landmark the least over the drills. The clearance at the stop would be
  the margin itself whenever the margin stops the drill, so it is not what the table shows.
- **The implant** (:func:`implant_check`, the one function the window calls for the implant
  body's clearance, its bone walls and their warnings, with the same messages as the
  outputs): the engine's :func:`~ctdrill.engine.implant.implant_outcome`, taken from the path
  result (``PathResult.implant``) when the path computed it.
- **Problems** (:data:`PROBLEM_CODES`, codes of :mod:`ctdrill.warning_codes`): the path's own
  warnings with these codes, the implant's, and every drill of a sequence that breaks a margin
  at its drilled depth; each code and message once, in the order of :data:`PROBLEM_CODES`.
- **Digits**: clearances are written with the digits the CT supports
  (:func:`~ctdrill.imaging.resolution.format_clearance_mm`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from ctdrill.engine.implant import ImplantOutcome, implant_outcome
from ctdrill.engine.verdict import PlanVerdict, banner_problems, set_findings
from ctdrill.imaging.plan.implant_checks import implants_too_close
from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.resolution import format_clearance_mm
from ctdrill.imaging.volume import CTVolume
from ctdrill.warning_codes import LoadWarning, banner_codes, words

#: The plan problems the banner lists, in this order: the registry's ``banner`` codes
#: (:func:`ctdrill.warning_codes.banner_codes`; their headings, ``words``).
PROBLEM_CODES = banner_codes()


def implant_check(
    volume: CTVolume,
    plan: Plan,
    landmarks: tuple[Landmark, ...] | None = None,
) -> ImplantOutcome | None:
    """The implant body of ``plan`` on ``volume`` (the engine's
    :func:`~ctdrill.engine.implant.implant_outcome`: its clearance to ``landmarks``, default
    the plan's, masks bound to the CT grid; its bone walls on the full grid, also while it is
    dragged; the CT's accuracy and the warnings as the outputs word them); None without an
    implant."""
    if landmarks is not None:
        plan = replace(plan, landmarks=landmarks)
    return implant_outcome(volume, plan)


@dataclass(frozen=True, eq=False)
class PlannedClearance:
    """The planned clearances the landmark table shows, per landmark in plan order, mm.

    Attributes
    ----------
    margins_mm : (L,) the margin that applies to each.
    osteotomy_mm : (L,) the least clearance of the drills at their planned depths.
    osteotomy_drill : (L,) which drill that is (0-based).
    implant_mm : (L,) the implant body's clearance, or None without an implant.
    accuracy_mm : what the CT lets a clearance claim, +- mm (sets the digits).
    """

    margins_mm: np.ndarray
    osteotomy_mm: np.ndarray
    osteotomy_drill: np.ndarray
    implant_mm: np.ndarray | None
    accuracy_mm: float

    def broken(self) -> np.ndarray:
        """(L,) bool: the osteotomy or the implant breaks the landmark's margin."""
        out = self.osteotomy_mm < self.margins_mm
        if self.implant_mm is not None:
            out = out | (self.implant_mm < self.margins_mm)
        return np.asarray(out, dtype=bool)

    def text(self, value_mm: float) -> str:
        """``value_mm`` with the digits the CT supports and its unit (``"0.8 mm"``)."""
        return f"{format_clearance_mm(value_mm, self.accuracy_mm)} mm"


def planned_clearance(verdict: PlanVerdict, accuracy_mm: float) -> PlannedClearance:
    """The planned clearances of the plan of ``verdict`` (landmarks on the CT grid): its
    drills' as drilled and its implant body's."""
    implant = verdict.implant
    body = None if implant is None or implant.clearance is None else implant.clearance
    return PlannedClearance(
        margins_mm=verdict.margins_mm,
        osteotomy_mm=verdict.osteotomy_mm,
        osteotomy_drill=verdict.osteotomy_drill,
        implant_mm=None if body is None else np.asarray(body.clearance_mm, dtype=np.float64),
        accuracy_mm=accuracy_mm,
    )


def set_problems(
    plans: Sequence[Plan], index: int, close: dict[str, tuple[LoadWarning, ...]] | None = None
) -> list[LoadWarning]:
    """The geometric problems of ``plans[index]`` that need no CT: ``implant_above_entry``
    (:func:`ctdrill.engine.verdict.set_findings`) and ``implants_too_close`` with the others
    of the set (the outputs' messages; ``close``: the set's
    :func:`~ctdrill.imaging.plan.implant_checks.implants_too_close`, when known)."""
    plan = plans[index]
    above = list(set_findings(plan))
    pairs = implants_too_close(tuple(plans)) if close is None else close
    return above + list(pairs.get(plan.name, ()))


def plan_problems(*sources: Iterable[LoadWarning]) -> tuple[LoadWarning, ...]:
    """The problems among ``sources``: those the banner shows, each once, by rank
    (:func:`ctdrill.engine.verdict.banner_problems`)."""
    return banner_problems(*sources)


def problems_text(problems: Sequence[LoadWarning]) -> str:
    """The banner's lines: ``code (words): message``, one per problem."""
    return "\n".join(f"• {words(w.code)} ({w.code}): {w.message}" for w in problems)


#: Written before a planned clearance below the landmark's margin (the landmark table).
VIOLATED_MARK = "\u2717"
#: A table cell: ``(text, tooltip, below the margin)``.
Cell = tuple[str, str, bool]


def planned_cells(
    plan: Plan, planned: PlannedClearance, at_stop_mm: np.ndarray | None = None
) -> list[tuple[Cell, Cell]]:
    """The landmark table's implant and osteotomy cells of each landmark of ``plan``: the
    planned clearance with the CT's digits, after :data:`VIOLATED_MARK` below the margin, and
    a tooltip saying what was measured and to what accuracy (``at_stop_mm``: the clearance
    at the stop, (L,))."""
    out = []
    for j, lm in enumerate(plan.landmarks):
        margin = float(planned.margins_mm[j])
        margin_text = f"margin {margin:g} mm"
        if planned.implant_mm is None:
            implant: Cell = ("no implant", "no implant is placed on this trajectory", False)
        else:
            value = float(planned.implant_mm[j])
            broken = value < margin
            implant = (
                _marked(planned.text(value), broken),
                f"implant body at its placement to {lm.name!r}: {planned.text(value)} "
                f"({margin_text})"
                + (": the implant breaks the margin" if broken else "")
                + _known(planned),
                broken,
            )
        value = float(planned.osteotomy_mm[j])
        k = int(planned.osteotomy_drill[j])
        drilled = plan.drilled(k)
        broken = value < margin
        tip = (
            f"drill {k + 1} of {len(plan.drills)} ({drilled.drill.diameter_mm:g} mm) at its "
            f"planned depth {drilled.planned_depth_mm:.2f} mm to {lm.name!r}: "
            f"{planned.text(value)} ({margin_text})"
            + (": the osteotomy breaks the margin" if broken else "")
            + _known(planned)
        )
        if at_stop_mm is not None and len(at_stop_mm) == len(plan.landmarks):
            tip += f"; the final drill at its stop: {planned.text(float(at_stop_mm[j]))}"
        osteotomy = (_marked(planned.text(value), broken), tip, broken)
        out.append((implant, osteotomy))
    return out


class _Checked(Protocol):
    """What :func:`offending_implants` reads of a path view."""

    @property
    def plan(self) -> Plan: ...
    @property
    def problems(self) -> tuple[LoadWarning, ...]: ...


def offending_implants(
    plans: Sequence[Plan], views: Sequence[_Checked | None] = ()
) -> tuple[bool, ...]:
    """Per trajectory, whether its implant is drawn red: it has an implant and a plan problem,
    from its path result when one was computed for it (``views[i]``, aligned with ``plans``)
    or from the problems the set shows without a CT (:func:`set_problems`)."""
    close = implants_too_close(tuple(plans))
    out = []
    for i, plan in enumerate(plans):
        view = views[i] if i < len(views) else None
        own = view is not None and view.plan is plan and bool(view.problems)
        out.append(plan.implant is not None and (own or bool(set_problems(plans, i, close))))
    return tuple(out)


def _marked(text: str, broken: bool) -> str:
    return f"{VIOLATED_MARK} {text}" if broken else text


def _known(planned: PlannedClearance) -> str:
    return f" (the CT's sampling: +-{planned.accuracy_mm:.2g} mm)"
