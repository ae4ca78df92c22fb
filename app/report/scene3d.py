"""The report's 3D view: the window's scene of the case, rendered off screen into an image."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ctdrill.app.export_run import PreparedCase
from ctdrill.app.report.entries import Entry

#: Largest number of samples along any axis of the volume the report's bone surface is made
#: from (the window's default: ``ctdrill.app.gui.compute.SURFACE_MAX_DIM``).
SURFACE_MAX_DIM = 160


def render_case(
    case: PreparedCase, entries: Sequence[Entry], *, size_px: tuple[int, int]
) -> np.ndarray:
    """(H, W, 3) uint8 image of the bone surface with every trajectory of ``entries``."""
    import pyvista as pv

    from ctdrill.app.gui.compute import volume_surface
    from ctdrill.app.gui.planning import scene_input
    from ctdrill.app.gui.results import path_view
    from ctdrill.app.gui.scene import build_scene, focus_camera

    surface = volume_surface(case.volume, max_dim=SURFACE_MAX_DIM)
    first = entries[0]
    view = path_view(first.result.plan, first.result)
    scene = scene_input(first.result.plan, view)
    plotter = pv.Plotter(off_screen=True, window_size=list(size_px))
    try:
        build_scene(plotter, scene, surface=surface)
        focus_camera(
            plotter,
            first.result.plan.entry_lps,
            first.result.plan.target_lps,
            bounds=surface.bounds if surface.n_points else None,
        )
        img = plotter.screenshot(return_img=True)
    finally:
        plotter.close()
    return np.ascontiguousarray(np.asarray(img)[..., :3], dtype=np.uint8)
