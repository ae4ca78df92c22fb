"""What a command knows of its plans before computing them: the set's warnings, the calibration."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from ctdrill.imaging.plan.drill_spec import tip_override_warnings
from ctdrill.imaging.plan.implant_checks import implants_too_close
from ctdrill.imaging.plan.load import load_plan_set, pick_plan
from ctdrill.imaging.plan.protocol import final_drill_warnings
from ctdrill.imaging.plan.types import Plan
from ctdrill.model.calibration import Calibration, load_calibration

__all__ = ["one_trajectory", "plan_calibration", "plan_calibration_key", "with_set_warnings"]


def with_set_warnings(plans: Sequence[Plan]) -> tuple[Plan, ...]:
    """``plans`` each carrying the warnings only the whole set shows (``implants_too_close``,
    :func:`~ctdrill.imaging.plan.implant_checks.implants_too_close`) and only the whole
    trajectory shows, not one drill's view of it (``final_drill_mismatch``,
    ``drill_tip_override``,
    :func:`~ctdrill.imaging.plan.protocol.final_drill_warnings`) in ``Plan.warnings``, so
    that :func:`plan_path` reports them with the rest; call it where a command sees every
    trajectory of a plan set, after its last edit."""
    seq = tuple(plans)
    extra = implants_too_close(seq)
    out = []
    for p in seq:
        more = [
            *extra.get(p.name, ()),
            *final_drill_warnings(p),
            *tip_override_warnings(p.drills, f"plan {p.name!r}"),
        ]
        out.append(replace(p, warnings=(*p.warnings, *more)) if more else p)
    return tuple(out)


def plan_calibration_key(plan: Plan) -> str:
    """What to pass to :func:`ctdrill.model.load_calibration` for the plan's set: a bundled name as
    written, a path relative to the plan file resolved beside it."""
    key = plan.calibration
    candidate = Path(key)
    if plan.source and not candidate.is_absolute() and ("/" in key or key.endswith(".json")):
        beside = Path(plan.source).parent / candidate
        if beside.is_file():
            key = str(beside)
    return key


def plan_calibration(plan: Plan) -> Calibration:
    """The plan's calibration set (see :func:`plan_calibration_key`).

    Raises
    ------
    model.calibration.CalibrationError
        The set is missing or invalid (the message names the file and field).
    """
    return load_calibration(plan_calibration_key(plan))


def one_trajectory(paths: Sequence[str | os.PathLike[str]], trajectory: str | None = None) -> Plan:
    """The one trajectory a command drills (``rehearse``): picked as
    :func:`~ctdrill.imaging.plan.load.load_one_plan` picks it, carrying the warnings of its
    whole plan set (:func:`with_set_warnings`), as the export of the same files gives them."""
    return pick_plan(with_set_warnings(load_plan_set(paths)), trajectory)
