"""The 3D scene rendered off screen into an array (``ctdrill report``): the same scene and the same
starting camera as the window's 3D view, on a :class:`ctdrill.app.gui.stage.Stage` (an EGL render
window: no display needed; see DESIGN §6)."""

from __future__ import annotations

import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonCore import vtkLogger

from ctdrill.app.gui.camera import apply_camera
from ctdrill.app.gui.scene import SceneInput, build_scene, scene_camera
from ctdrill.app.gui.stage import Stage

#: MSAA samples of the report's image (pyvista's default, which the report was drawn with:
#: smooth edges, and the translucent bone blended in drawing order rather than VTK's
#: order-independent blending, which multisampling turns off).
REPORT_MULTI_SAMPLES = 8


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
    # Where EGL cannot be had VTK's default window may try X first and say so on stderr.
    cutoff = vtkLogger.GetCurrentVerbosityCutoff()
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    stage = Stage((width, height), multi_samples=REPORT_MULTI_SAMPLES)
    try:
        build_scene(stage, scene_input, surface=surface, bone_opacity=bone_opacity)
        pose = scene_camera(scene_input, surface)
        if pose is not None:
            apply_camera(stage, pose)
        img = stage.screenshot()
    finally:
        stage.close()
        vtkLogger.SetStderrVerbosity(vtkLogger.ConvertToVerbosity(cutoff))
    return np.ascontiguousarray(img, dtype=np.uint8)
