"""What a path's user must know: its warnings, gathered once, in a fixed order.

:data:`PATH_CHECKS` is the one list of per-trajectory checks: each reads the computed path (a
:class:`PathView`: the plan, the profile, the clearances, the stop) and the volume, and gives
warnings (:class:`~ctdrill.warning_codes.LoadWarning`). A new warning is one function here and
its code in :mod:`ctdrill.warning_codes`. :func:`path_warnings` gives them all, each code +
message once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Protocol

import numpy as np

from ctdrill.engine.budget import budget_warnings
from ctdrill.engine.implant import ImplantOutcome
from ctdrill.engine.refusals import gap_interpolated_message
from ctdrill.imaging.plan.budget import MarginBudget
from ctdrill.imaging.plan.implant_checks import implant_warnings
from ctdrill.imaging.plan.safety import margin_warnings
from ctdrill.imaging.plan.types import Plan, plan_warnings, series_uid_hash
from ctdrill.imaging.sampling.path import SliceGap
from ctdrill.imaging.volume import CTVolume, LoadWarning
from ctdrill.model.calibration import Calibration
from ctdrill.model.force import feed_outside_model
from ctdrill.model.profile import Profile


class PathView(Protocol):
    """What the checks read of a computed path (:class:`ctdrill.engine.path.PathResult`)."""

    @property
    def plan(self) -> Plan: ...
    @property
    def profile(self) -> Profile: ...
    @property
    def calibration(self) -> Calibration: ...
    @property
    def clearance_mm(self) -> np.ndarray: ...
    @property
    def margins_mm(self) -> np.ndarray: ...
    @property
    def stop_depth_mm(self) -> float: ...
    @property
    def stop_reason(self) -> str: ...
    @property
    def interpolated_gaps(self) -> tuple[SliceGap, ...]: ...
    @property
    def implant(self) -> ImplantOutcome | None: ...
    @property
    def budgets(self) -> tuple[MarginBudget, ...]: ...


Found = Iterable[LoadWarning]
#: A per-trajectory check: the volume and the computed path -> its warnings.
PathCheck = Callable[[CTVolume, PathView], Found]


def _series(volume: CTVolume, path: PathView) -> Found:
    return volume.warnings


def _plan_file(volume: CTVolume, path: PathView) -> Found:
    return plan_warnings(path.plan)


def _gaps(volume: CTVolume, path: PathView) -> Found:
    return [
        LoadWarning("gap_interpolated", gap_interpolated_message(path.plan, g))
        for g in path.interpolated_gaps
    ]


def _margins(volume: CTVolume, path: PathView) -> Found:
    at_plan = path.clearance_mm[-1] if path.plan.landmarks else np.empty(0)
    return margin_warnings(path.plan, at_plan, path.margins_mm)


def _implant_body(volume: CTVolume, path: PathView) -> Found:
    """The implant's own: its margin (``implant_violates_margin`` and the plan's
    ``plan_violates_margin``), its walls (``thin_wall``, ``cortical_perforation``,
    ``bone_walls_unknown``)."""
    return () if path.implant is None else path.implant.warnings


def _budget(volume: CTVolume, path: PathView) -> Found:
    """``margin_below_budget`` (:func:`~ctdrill.engine.budget.budget_warnings`)."""
    if not path.budgets or not path.plan.landmarks:
        return ()
    body = None
    if path.implant is not None and path.implant.clearance is not None:
        body = path.implant.clearance.clearance_mm
    return budget_warnings(path.plan, path.budgets, path.margins_mm, path.clearance_mm[-1], body)


def _other_series(volume: CTVolume, path: PathView) -> Found:
    plan = path.plan
    if plan.series_uid_sha256 is None or plan.series_uid_sha256 == series_uid_hash(
        volume.info.series_uid
    ):
        return ()
    return [
        LoadWarning(
            "plan_other_series",
            f"plan {plan.name!r} was made on another series than the one loaded (its "
            "recorded series hash differs): check that the CT and the plan belong together",
        )
    ]


def _illustrative(volume: CTVolume, path: PathView) -> Found:
    cal = path.calibration
    if not cal.illustrative:
        return ()
    return [
        LoadWarning(
            "calibration_illustrative",
            f"calibration {cal.name!r} is illustrative (not measured on bone): "
            "forces show the pattern, not validated magnitudes",
        )
    ]


def _feed(volume: CTVolume, path: PathView) -> Found:
    note = feed_outside_model(path.plan.feed_mm_s, path.calibration)
    return (
        ()
        if note is None
        else [LoadWarning("feed_outside_model", f"plan {path.plan.name!r}: {note}")]
    )


def _extrapolated(volume: CTVolume, path: PathView) -> Found:
    prof = path.profile
    if not prof.n_clipped:
        return ()
    return [
        LoadWarning(
            "extrapolated",
            f"{prof.n_clipped} of {prof.n_samples} cut lip samples lie outside the "
            f"calibration's C' range {list(path.calibration.c_prime_range)}; clipped to it",
        )
    ]


def _implant(volume: CTVolume, path: PathView) -> Found:
    return implant_warnings(path.plan, float(path.stop_depth_mm), path.stop_reason)


def _left_volume(volume: CTVolume, path: PathView) -> Found:
    if path.stop_reason != "out_of_volume":
        return ()
    return [
        LoadWarning(
            "out_of_volume",
            f"plan {path.plan.name!r}: the drill leaves the CT volume at "
            f"{path.stop_depth_mm:.3f} mm, before the planned depth "
            f"{path.plan.planned_depth_mm:.3f} mm",
        )
    ]


#: Every per-trajectory check, in the order the warnings are listed.
PATH_CHECKS: tuple[PathCheck, ...] = (
    _series,
    _plan_file,
    _gaps,
    _margins,
    _implant_body,
    _budget,
    _other_series,
    _illustrative,
    _feed,
    _extrapolated,
    _implant,
    _left_volume,
)


def dedupe_warnings(warnings: Sequence[LoadWarning]) -> tuple[LoadWarning, ...]:
    """``warnings`` in order, each (code, message) once."""
    seen: set[LoadWarning] = set()
    out: list[LoadWarning] = []
    for w in warnings:
        if w not in seen:
            seen.add(w)
            out.append(w)
    return tuple(out)


def path_warnings(volume: CTVolume, path: PathView) -> tuple[LoadWarning, ...]:
    """Every check of :data:`PATH_CHECKS` on ``path``, each code + message once."""
    return dedupe_warnings([w for check in PATH_CHECKS for w in check(volume, path)])
