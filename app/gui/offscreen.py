"""The 3D scene rendered off screen into an array (``ctdrill report``): the same scene and the same
starting camera as the window's 3D view, with ``pyvista.Plotter(off_screen=True)``, which needs
no display (it falls back from X to EGL; see DESIGN §6)."""

from __future__ import annotations

import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonCore import vtkLogger

from ctdrill.app.gui.camera import apply_camera
from ctdrill.app.gui.scene import SceneInput, build_scene, scene_camera


def render_offscreen(
    surface: pv.PolyData | None,
    scene_input: SceneInput,
    *,
    size_px: tuple[int, int] = (800, 600),
    bone_opacity: float = 0.45,
) -> np.ndarray:
    """Render ``scene_input`` over the bone ``surface`` (may be None or empty) off screen.

    Parameters
    ----------
    surface : the bone surface (``bone_surface`` / ``compute.volume_surface``).
    scene_input : the plan geometry, as the window draws it.
    size_px : (width, height) of the image, pixels (each at least 16).
    bone_opacity : 0..1, as in the window.

    Returns
    -------
    (height, width, 3) uint8 RGB image.
    """
    width, height = (int(size_px[0]), int(size_px[1]))
    if width < 16 or height < 16:
        raise ValueError(f"size_px: expected at least 16 x 16 pixels, got {size_px}")
    # Without a display VTK tries X first and says so on stderr before falling back to EGL.
    cutoff = vtkLogger.GetCurrentVerbosityCutoff()
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    plotter = pv.Plotter(off_screen=True, window_size=[width, height])
    try:
        build_scene(plotter, scene_input, surface=surface, bone_opacity=bone_opacity)
        pose = scene_camera(scene_input, surface)
        if pose is not None:
            apply_camera(plotter, pose)
        img = plotter.screenshot(return_img=True)
    finally:
        plotter.close()
        vtkLogger.SetStderrVerbosity(vtkLogger.ConvertToVerbosity(cutoff))
    return np.ascontiguousarray(np.asarray(img)[..., :3], dtype=np.uint8)
