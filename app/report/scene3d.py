"""The report's 3D view: the window's scene of the case, rendered off screen into an image.

The bone surface is the window's (:func:`ctdrill.app.gui.compute.volume_surface` with its
defaults), the scene the window's for the first trajectory
(:func:`ctdrill.app.gui.planning.scene_input`: its drill to the stop, the landmarks with their
clearance colours) plus every trajectory's implant body and the other trajectories' axes, the
dental arch for the camera; :func:`ctdrill.app.gui.offscreen.render_offscreen` draws it with
the window's starting camera, no display needed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ctdrill.app.report.entries import Entry
from ctdrill.engine.case import PreparedCase


def render_case(
    case: PreparedCase, entries: Sequence[Entry], *, size_px: tuple[int, int]
) -> np.ndarray:
    """(H, W, 3) uint8 image of the bone surface with every trajectory of ``entries`` (the
    first one as the window's current trajectory)."""
    from ctdrill.app.gui.compute import volume_surface
    from ctdrill.app.gui.offscreen import render_offscreen
    from ctdrill.app.gui.planning import scene_input
    from ctdrill.app.gui.results import path_view
    from ctdrill.app.gui.scene import ImplantGeometry, TrajectoryLine
    from ctdrill.imaging.plan.implants import implant_placement

    first = entries[0].result
    implants = []
    for k, entry in enumerate(entries):
        placed = implant_placement(entry.result.plan)
        if placed is None:
            continue
        s_mm, r_mm = placed.spec.profile_mm()
        implants.append(
            ImplantGeometry(
                name=entry.label,
                platform_lps=placed.platform_lps,
                axis_lps=placed.axis_lps,
                s_mm=s_mm,
                r_mm=r_mm,
                current=k == 0,
            )
        )
    others = tuple(
        TrajectoryLine(
            name=e.label,
            entry_lps=e.result.plan.entry_lps,
            target_lps=e.result.plan.target_lps,
            diameter_mm=e.result.plan.drill.diameter_mm,
        )
        for e in entries[1:]
    )
    scene = replace(
        scene_input(first.plan, path_view(first.plan, first)),
        implants=tuple(implants),
        others=others,
        arch_lps=first.plan.arch_lps,
    )
    return render_offscreen(volume_surface(case.volume), scene, size_px=size_px)
