"""Does this plan break a rule? The plan's verdict on one CT, computed once.

:func:`plan_verdict` gathers every finding of a trajectory: every drill of its osteotomy as it
is drilled (:meth:`~ctdrill.imaging.plan.types.Plan.drilled`: to the implant's apex plus the
drill's tip) against every landmark's margin at its planned depth, the implant body and its
bone walls (:func:`ctdrill.engine.implant.implant_outcome`), the checks of the plan set
(``implant_above_entry``; ``implants_too_close`` arrives with the path's warnings, from
:func:`ctdrill.engine.plans.with_set_warnings`), and the computed path's own warnings when a
path is given. The window's banner and landmark table (:mod:`ctdrill.app.gui.results`) and
``suggest``'s feasibility (:mod:`ctdrill.app.search.feasibility`) read a :class:`PlanVerdict`;
what a code means to them (blocks ``suggest``, shows in the banner, its words) is the warning
registry's (:mod:`ctdrill.warning_codes`). Every finding is a
:class:`~ctdrill.imaging.volume.LoadWarning`, its message built from the values it reports.

A new check is one function here that yields its findings (its code registered with
``blocks_suggest`` / ``banner`` as it should act): every reader sees it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ctdrill.engine.implant import ImplantOutcome, implant_outcome
from ctdrill.engine.path import PathResult
from ctdrill.engine.stop import StopReason
from ctdrill.imaging.plan.implant_checks import implant_warnings
from ctdrill.imaging.plan.landmarks import bind_to_grid
from ctdrill.imaging.plan.safety import clearance_profile_mm, margin_warnings, margins_mm
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume, LoadWarning
from ctdrill.warning_codes import WARNINGS, banner_codes

#: The code of a drill's broken margin at its drilled depth.
DRILL_MARGIN = "plan_violates_margin"
#: The set check that needs no CT (the implant's platform above the entry).
ABOVE_ENTRY = "implant_above_entry"
#: Blocks ``suggest`` only when no wall at all is known (some directions unknown, the known
#: ones decide).
WALLS_UNKNOWN = "bone_walls_unknown"


@dataclass(frozen=True, eq=False)
class PlanVerdict:
    """Every finding of one trajectory on one CT (module docstring).

    Attributes
    ----------
    plan : the plan, landmarks bound to the CT grid.
    drill_clearance_mm : (K, L) each drill as drilled, at its planned depth, to each landmark,
        mm.
    drill_findings : per drill, its broken margin (``plan_violates_margin``), or nothing.
    implant : the implant outcome, or None without an implant.
    set_findings : the set's checks needing no CT (``implant_above_entry``).
    path_findings : the computed path's own warnings (its drill's margin left to
        ``drill_findings`` when the path was computed to the apex only), or none.
    """

    plan: Plan
    drill_clearance_mm: np.ndarray
    drill_findings: tuple[tuple[LoadWarning, ...], ...]
    implant: ImplantOutcome | None
    set_findings: tuple[LoadWarning, ...]
    path_findings: tuple[LoadWarning, ...] = ()

    @property
    def margins_mm(self) -> np.ndarray:
        """(L,) the margin that applies to each landmark, mm."""
        return margins_mm(self.plan)

    @property
    def osteotomy_mm(self) -> np.ndarray:
        """(L,) the least planned clearance over the drills, mm."""
        c = self.drill_clearance_mm
        return c.min(axis=0) if c.shape[0] and c.shape[1] else np.zeros(c.shape[1])

    @property
    def osteotomy_drill(self) -> np.ndarray:
        """(L,) which drill (0-based) gives :attr:`osteotomy_mm`."""
        c = self.drill_clearance_mm
        if not (c.shape[0] and c.shape[1]):
            return np.zeros(c.shape[1], dtype=np.int64)
        return np.argmin(c, axis=0)

    @property
    def implant_findings(self) -> tuple[LoadWarning, ...]:
        """The implant body's and its walls' findings."""
        if self.implant is None:
            return ()
        return tuple(self.implant.warnings)

    @property
    def findings(self) -> tuple[LoadWarning, ...]:
        """Every finding, each code and message once: the path's, the implant's, every
        drill's, the set's."""
        seen: dict[LoadWarning, None] = {}
        for w in (
            *self.path_findings,
            *self.implant_findings,
            *(w for drill in self.drill_findings for w in drill),
            *self.set_findings,
        ):
            seen.setdefault(w)
        return tuple(seen)

    def problems(self) -> tuple[LoadWarning, ...]:
        """What the window's banner lists: the findings of the registry's ``banner`` codes,
        each once, by the code's rank."""
        return banner_problems(self.findings)

    def blocking(self) -> tuple[tuple[int | None, LoadWarning], ...]:
        """The findings that make the plan infeasible for ``suggest`` (the registry's
        ``blocks_suggest``; ``bone_walls_unknown`` only when no wall is known), each with its
        drill (0-based) or None: the drills' first, then the implant's."""
        out: list[tuple[int | None, LoadWarning]] = []
        for k, drill in enumerate(self.drill_findings):
            out += [(k, w) for w in drill if WARNINGS[w.code].blocks_suggest]
        known_wall = self.implant is not None and self.implant.walls.min_mm is not None
        for w in self.implant_findings:
            if w.code == WALLS_UNKNOWN and known_wall:
                continue
            if WARNINGS[w.code].blocks_suggest:
                out.append((None, w))
        return tuple(out)

    @property
    def feasible(self) -> bool:
        """No finding blocks ``suggest``."""
        return not self.blocking()


def banner_problems(*sources: Iterable[LoadWarning]) -> tuple[LoadWarning, ...]:
    """The warnings among ``sources`` the banner shows, each once, by the registry's
    ``banner`` rank."""
    order = banner_codes()
    found = dict.fromkeys(w for source in sources for w in source if w.code in order)
    return tuple(sorted(found, key=lambda w: order.index(w.code)))


def drill_clearances_mm(plan: Plan, drilled: tuple[Plan, ...] | None = None) -> np.ndarray:
    """(K, L) planned clearance of each drill of ``plan`` (drilled to its planned depth) to
    each landmark (masks bound to the CT grid), mm; ``drilled`` the plans
    ``plan.drilled(k)`` when already built."""
    n_l = len(plan.landmarks)
    if drilled is None:
        drilled = tuple(plan.drilled(k) for k in range(len(plan.drills)))
    rows = [clearance_profile_mm(d)[0] for d in drilled]
    return np.array(rows, dtype=np.float64).reshape(len(plan.drills), n_l)


def _same_drill(a: Plan, b: Plan) -> bool:
    """The same drill to the same planned tip (the path result computed for this drill)."""
    return a.drill == b.drill and bool(np.allclose(a.target_lps, b.target_lps, atol=1e-9, rtol=0))


def _drill_findings(
    plan: Plan, drilled_plans: tuple[Plan, ...], clearance_mm: np.ndarray, covered: Plan | None
) -> tuple[tuple[LoadWarning, ...], ...]:
    margins = margins_mm(plan)
    out: list[tuple[LoadWarning, ...]] = []
    for k, drilled in enumerate(drilled_plans):
        if covered is not None and _same_drill(drilled, covered):
            out.append(())  # the path's own warnings say it, with the export's numbers
            continue
        found = margin_warnings(drilled, clearance_mm[k], margins)
        out.append(tuple(w for w in found if w.code == DRILL_MARGIN))
    return tuple(out)


def set_findings(plan: Plan) -> tuple[LoadWarning, ...]:
    """The set's checks of ``plan`` that need no CT: ``implant_above_entry``."""
    above = implant_warnings(plan, plan.planned_depth_mm, StopReason.PLANNED_DEPTH)
    return tuple(w for w in above if w.code == ABOVE_ENTRY)


def plan_verdict(
    volume: CTVolume,
    plan: Plan,
    *,
    path: PathResult | None = None,
    implant: ImplantOutcome | None = None,
    **wall_options: Any,
) -> PlanVerdict:
    """The verdict of ``plan`` on ``volume`` (module docstring).

    Parameters
    ----------
    volume : the CT (LPS); mask landmarks take its grid.
    plan : the trajectory (every drill, its implant).
    path : the path computed for it (its warnings join the findings; a path computed to the
        implant's apex only has its drill-margin warning replaced by the drilled one).
    implant : the implant outcome when already computed (the path's, a drag's coarser walls);
        else computed here with ``wall_options``.
    """
    lms = bind_to_grid(plan.landmarks, volume.affine_lps, tuple(volume.hu.shape))
    if any(a is not b for a, b in zip(lms, plan.landmarks, strict=True)):
        plan = replace(plan, landmarks=lms)
    if implant is None and path is not None:
        implant = path.implant
    if implant is None and plan.implant is not None:
        implant = implant_outcome(volume, plan, **wall_options)
    own: tuple[LoadWarning, ...] = ()
    covered = None
    if path is not None:
        to_apex = plan.implant is not None and path.plan.overdrill_mm == 0.0
        own = tuple(w for w in path.warnings if not (to_apex and w.code == DRILL_MARGIN))
        covered = None if to_apex else path.plan
    drilled = tuple(plan.drilled(k) for k in range(len(plan.drills)))  # each built once
    clearance = drill_clearances_mm(plan, drilled)
    return PlanVerdict(
        plan=plan,
        drill_clearance_mm=clearance,
        drill_findings=_drill_findings(plan, drilled, clearance, covered),
        implant=implant,
        set_findings=set_findings(plan),
        path_findings=own,
    )
