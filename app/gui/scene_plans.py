"""The 3D scene of every trajectory of a plan file: the selected one drawn in full (drill, path,
stop, landmarks with their clearances, via :func:`ctdrill.app.gui.planning.scene_input`), every
trajectory's implant body from :func:`ctdrill.imaging.plan.implants.implant_placement` and
``ImplantSpec.profile_mm()`` (the selected one's highlighted), the other trajectories as lines,
and the dental arch (the camera looks from outside it)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ctdrill.app.gui.planning import scene_input
from ctdrill.app.gui.problems import offending_implants
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.scene import CandidateLine, ImplantGeometry, SceneInput, TrajectoryLine
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.types import Plan


def implant_geometry(
    plan: Plan, *, current: bool = True, offending: bool = False
) -> ImplantGeometry | None:
    """The implant body of ``plan`` as drawn (apex at the target, platform ``length_mm`` back
    along the axis; ``offending``: red), or None when the plan has no implant."""
    placement = implant_placement(plan)
    if placement is None:
        return None
    s_mm, r_mm = placement.spec.profile_mm()
    return ImplantGeometry(
        name=placement.spec.name,
        platform_lps=np.asarray(placement.platform_lps, dtype=np.float64),
        axis_lps=np.asarray(placement.axis_lps, dtype=np.float64),
        s_mm=np.asarray(s_mm, dtype=np.float64),
        r_mm=np.asarray(r_mm, dtype=np.float64),
        current=current,
        offending=offending,
    )


def plans_scene(
    plans: Sequence[Plan],
    current: int,
    view: PathView | None,
    candidates: tuple[CandidateLine, ...] = (),
    views: Sequence[PathView | None] = (),
) -> SceneInput:
    """The scene of ``plans`` with ``plans[current]`` selected (no plans: the anatomy alone).

    ``view`` is the path result (its stop and clearances are drawn when computed for the
    selected plan); ``candidates`` the suggested axes around it; ``views`` the results known
    for the others (aligned with ``plans``): an implant with a plan problem is drawn red
    (:func:`~ctdrill.app.gui.problems.offending_implants`).
    """
    if not plans:
        return scene_input(None, None)
    sel = plans[current]
    base = scene_input(sel, view, candidates)
    known = [
        view if i == current else (views[i] if i < len(views) else None) for i in range(len(plans))
    ]
    red = offending_implants(plans, known)
    implants = []
    for i, plan in enumerate(plans):
        geom = implant_geometry(plan, current=i == current, offending=red[i])
        if geom is not None:
            implants.append(geom)
    others = tuple(
        TrajectoryLine(
            name=plan.name,
            entry_lps=np.asarray(plan.entry_lps, dtype=np.float64),
            target_lps=np.asarray(plan.target_lps, dtype=np.float64),
            diameter_mm=float(plan.drill.diameter_mm),
        )
        for i, plan in enumerate(plans)
        if i != current
    )
    arch = sel.arch_lps
    return replace(
        base,
        implants=tuple(implants),
        others=others,
        arch_lps=None if arch is None else np.asarray(arch, dtype=np.float64),
    )
