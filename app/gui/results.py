"""What the window shows of a planned path: ``ctdrill.engine.path.plan_path``'s result turned into
plot curves, per-landmark clearances, the plan's problems (:mod:`ctdrill.app.gui.problems`: the
implant, the planned clearances, the banner's list) and the reason rehearsal is blocked, if
any."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ctdrill.app.gui.plots import DepthCurves
from ctdrill.app.gui.problems import (
    PlannedClearance,
    planned_clearance,
)
from ctdrill.engine.band import path_band
from ctdrill.engine.implant import ImplantOutcome, implant_outcome
from ctdrill.engine.path import PathResult, complete_path, path_curves, plan_path
from ctdrill.engine.plans import plan_calibration, with_set_warnings
from ctdrill.engine.sequence import plan_sequence
from ctdrill.engine.stop import stop_words
from ctdrill.engine.verdict import plan_verdict
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.resolution import volume_clearance_accuracy_mm
from ctdrill.model.band import HuUncertainty
from ctdrill.warning_codes import LoadWarning


@dataclass(frozen=True, eq=False)
class PathView:
    """A path result and its display form, for the plan it was computed for.

    ``implant``, ``planned`` and ``problems`` are filled by :func:`compute_path_view` (the
    implant body's check, the planned clearances of the implant and of the osteotomy, the
    plan problems as warnings); a bare :func:`path_view` leaves them empty."""

    plan: Plan
    result: PathResult
    curves: DepthCurves
    min_clearance_mm: np.ndarray | None  # (L,) per landmark along the stopped path
    implant: ImplantOutcome | None = None
    planned: PlannedClearance | None = None
    problems: tuple[LoadWarning, ...] = ()


def path_view(plan: Plan, result: PathResult, hu: HuUncertainty | None = None) -> PathView:
    """Plot curves and clearances of ``result`` (computed for ``plan``); the mean force's band
    with the HU uncertainty ``hu`` (``ctdrill gui --hu-sigma``)."""
    prof = result.profile
    band = np.sum(np.abs(prof.sk_n), axis=0) if prof.sk_n.size else None
    mean_band = path_band(result, plan.feed_mm_s, hu)
    note = (
        f"no uncertainty band: {result.calibration.name} gives no covariance"
        if mean_band is None
        else "blue: 68 % band of the mean (calibration" + (" + HU)" if hu is not None else ")")
    )
    if band is not None:
        # the orange envelope is the 30/60 Hz vibration the device adds, not an uncertainty
        note = f"orange: vibration range; {note}"
    per_lm = np.asarray(result.stop_clearance_mm, dtype=np.float64)
    curves = DepthCurves(
        depth_mm=np.asarray(prof.depth_mm),
        hu=np.asarray(prof.hu_mean),
        force_n=prof.mean_force_n(plan.feed_mm_s),
        force_band_n=band,
        clearance_mm=np.asarray(result.min_clearance_per_depth_mm),
        planned_depth_mm=result.planned_depth_mm,
        stop_depth_mm=float(result.stop_depth_mm),
        stop_reason=str(result.stop_reason),
        margin_mm=result.binding_margin_mm,
        calibration=prof.calibration,
        mean_lo_n=None if mean_band is None else mean_band.lo_n,
        mean_hi_n=None if mean_band is None else mean_band.hi_n,
        band_note=note,
    )
    return PathView(
        plan=plan, result=result, curves=curves, min_clearance_mm=per_lm if per_lm.size else None
    )


def binding_index(result: PathResult) -> int | None:
    """The landmark whose margin sets the stop (``PathResult.binding_landmark``; the nearest
    one at the stop when none binds), None without landmarks."""
    return result.binding_landmark


def stop_explanation(result: PathResult) -> str:
    """Why the drill stops where it does, in words (which landmark, which margin), and for a
    drill of a sequence which drill it is (:func:`drill_note`)."""
    return _stop_words(result) + drill_note(result)


def _stop_words(result: PathResult) -> str:
    binding = binding_index(result)
    name = None if binding is None else result.landmarks[binding].name
    margin = None if binding is None else float(result.margins_mm[binding])
    return stop_words(
        result.stop_reason,
        form="sentence",
        landmark=name,
        margin_mm=margin,
        stop_mm=result.stop_depth_mm,
        planned_mm=result.planned_depth_mm,
    )


def plan_violation(result: PathResult) -> str | None:
    """The ``plan_violates_margin`` warning's message (the planned path breaks a margin), or
    None."""
    for warning in result.warnings:
        if warning.code == "plan_violates_margin":
            return warning.message
    return None


def compute_path_view(
    volume: CTVolume,
    plan: Plan,
    hu: HuUncertainty | None = None,
    *,
    plan_set: Sequence[Plan] = (),
    on_curves: Callable[[PathView], None] | None = None,
) -> PathView:
    """Plan the path of ``plan`` through ``volume`` (the pipeline the CLI uses) for display;
    ``hu`` enters the force band. ``plan_set`` (every trajectory of the document, ``plan``
    among them) adds the warnings only the whole set shows (``implants_too_close``,
    :func:`~ctdrill.engine.path.with_set_warnings`), as ``ctdrill export`` reports them.
    The view carries the plan's problems (:func:`checked`); the implant's walls are read on
    the full grid, also while a trajectory is dragged.

    ``on_curves`` (a drag's progressive display) is called first with the view of the path's
    curves and stop (:func:`~ctdrill.engine.path.path_curves`: the same numbers as the whole
    result's, without its implant check, warnings and problems); the rest is then computed
    and returned with the same curves. A drill sequence does not call it.

    For a drill sequence the window shows and rehearses the **final** drill, cutting around
    the holes the drills before it leave at their stop depths (the export's last folder,
    :mod:`ctdrill.engine.sequence`); ``ctdrill rehearse`` runs every drill."""
    own = _own(plan, plan_set)
    cal = plan_calibration(own)

    if len(own.drills) > 1:
        view = path_view(plan, plan_sequence(volume, own, cal).final, hu)
    elif on_curves is not None:  # the curves first, then the implant and the checks
        first = curves_view(volume, plan, hu, plan_set=plan_set)
        assert first is not None  # one drill
        on_curves(first)
        return completed_view(volume, first)
    else:  # to apex + tip
        view = path_view(plan, plan_path(volume, own.drilled(0), cal), hu)
    return checked(volume, view)


def _own(plan: Plan, plan_set: Sequence[Plan]) -> Plan:
    """``plan`` with the set's warnings (the view stays the document's own ``plan``)."""
    return next(
        (w for p, w in zip(plan_set, with_set_warnings(plan_set), strict=True) if p is plan), plan
    )


def curves_view(
    volume: CTVolume,
    plan: Plan,
    hu: HuUncertainty | None = None,
    *,
    plan_set: Sequence[Plan] = (),
) -> PathView | None:
    """The first stage of :func:`compute_path_view`: the view of ``plan``'s curves and stop
    (:func:`~ctdrill.engine.path.path_curves`), without the implant's check, warnings and
    problems; None for a drill sequence (computed in one stage)."""
    own = _own(plan, plan_set)
    if len(own.drills) > 1:
        return None
    return path_view(plan, path_curves(volume, own.drilled(0), plan_calibration(own)), hu)


def completed_view(volume: CTVolume, first: PathView) -> PathView:
    """The second stage: :func:`curves_view`'s ``first`` (whose result's plan carries the
    set's warnings) with the implant, the path's warnings and the checks (the same curves
    object: what the plots show stays)."""
    view = replace(first, result=complete_path(volume, first.result))
    return checked(volume, view)


def checked(volume: CTVolume, view: PathView) -> PathView:
    """``view`` with its implant check (the engine's outcome, ``PathResult.implant``, when the
    path computed one; else :func:`~ctdrill.app.gui.problems.implant_check`), planned
    clearances and problems: the path's warnings
    of :data:`~ctdrill.app.gui.problems.PROBLEM_CODES`, the implant's, and every drill's
    margin at its drilled depth (a path computed to the apex rather than drilled to the apex
    plus the tip has its drill-margin warning replaced by the drilled one)."""
    result, plan = view.result, view.plan
    with_lms = replace(plan, landmarks=result.landmarks)  # masks bound to the CT grid
    out = result.implant  # the engine's implant outcome (engine.implant.implant_outcome)
    if out is None and plan.implant is not None:
        out = implant_outcome(volume, with_lms)
    verdict = plan_verdict(volume, with_lms, path=result, implant=out)
    planned = planned_clearance(verdict, volume_clearance_accuracy_mm(volume))
    return replace(view, implant=verdict.implant, planned=planned, problems=verdict.problems())


def drill_note(result: PathResult) -> str:
    """Which drill of a sequence ``result`` is, and the holes it cuts around ("" for one)."""
    if not result.inner_holes:
        return ""
    holes = ", ".join(f"{2 * h.radius_mm:g} mm to {h.depth_mm:.2f} mm" for h in result.inner_holes)
    n = len(result.inner_holes) + 1
    return f" (drill {n}, {result.plan.drill.diameter_mm:g} mm, after {holes})"


def block_reason(
    volume: CTVolume | None, plan: Plan | None, view: PathView | None, error: str = ""
) -> str | None:
    """Why rehearsal must not start, or None. (A volume that cannot carry a force map, a
    single slice or values that are not HU, is refused by ``plan_path`` itself: no view.)"""
    if volume is None:
        return "no CT series loaded"
    if plan is None:
        return "no trajectory: right-click the target on a slice view, Shift+right-click the entry"
    if view is None:
        return f"no path: {error}" if error else "the path has not been computed"
    if view.curves.stop_depth_mm <= 0.0:
        why = stop_words(view.curves.stop_reason, form="code")
        return f"the drill cannot advance (stop reason: {why})"
    return None
