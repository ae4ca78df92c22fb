"""The 3D view's stage: a VTK renderer in an off-screen render window, built from raw
``vtkmodules`` (no ``pyvista.plotting``: it costs 0.8 s to import), with the few calls the scene
needs (:mod:`ctdrill.app.gui.scene`): add a mesh or an actor by name, point labels, a gradient
background, the orientation cube in a corner viewport, the camera, a frame read into an array.

The window's 3D view owns one on its render thread (:mod:`ctdrill.app.gui.render_thread`), the
report one on the calling thread (:mod:`ctdrill.app.gui.offscreen`): both draw the same scene.
The render window is EGL's (Mesa's EGL renders without a display and from any thread, with no
Xlib connection beside Qt's); where EGL cannot be had, VTK's default off-screen window.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any

import numpy as np

# The modules registering VTK's OpenGL and FreeType factory overrides (a render window, the
# text of the labels and of the orientation cube).
import vtkmodules.vtkRenderingFreeType
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkUnsignedCharArray
from vtkmodules.vtkRenderingCore import (
    vtkActor,
    vtkPolyDataMapper,
    vtkRenderer,
    vtkRenderWindow,
)

#: Fraction of the view (lower left) the orientation cube takes.
MARKER_SIZE = 0.2
#: Specular power of every surface (pyvista's default, which the scene was tuned with).
SPECULAR_POWER = 100.0

RGB = tuple[float, float, float]


def parse_colour(colour: str | Sequence[float]) -> RGB:
    """RGB 0..1 of a ``#rrggbb`` string or of an RGB triple (0..1)."""
    if isinstance(colour, str):
        h = colour.lstrip("#")
        if len(h) != 6:
            raise ValueError(f"colour {colour!r}: expected #rrggbb")
        return (int(h[0:2], 16) / 255.0, int(h[2:4], 16) / 255.0, int(h[4:6], 16) / 255.0)
    r, g, b = (float(c) for c in colour)
    return (r, g, b)


def egl_render_window() -> Any | None:
    """An off-screen EGL render window that can render (None when EGL cannot be had)."""
    try:
        from vtkmodules.vtkRenderingOpenGL2 import vtkEGLRenderWindow
    except ImportError:
        return None
    win = vtkEGLRenderWindow()
    win.SetOffScreenRendering(1)
    win.SetSize(8, 8)
    if not win.SupportsOpenGL():
        win.Finalize()
        return None
    return win


class Stage:
    """A renderer, its render window and the named props it shows.

    Every call but :meth:`__init__` must come from the thread that created it (the OpenGL
    context is current there); :attr:`thread` records it.

    Parameters
    ----------
    size_px : (width, height) of the frames, pixels.
    window : the render window to use (default: :func:`egl_render_window`, else VTK's default
        off-screen window).
    multi_samples : MSAA samples (0: none; software OpenGL pays dearly for them).
    """

    def __init__(
        self, size_px: tuple[int, int] = (400, 300), *, window: Any = None, multi_samples: int = 0
    ) -> None:
        self.thread = threading.current_thread()
        if window is None:
            window = egl_render_window()
        if window is None:
            window = vtkRenderWindow()
            window.SetOffScreenRendering(1)
        self.window = window
        self.egl = window.GetClassName() == "vtkEGLRenderWindow"
        window.SetMultiSamples(int(multi_samples))
        window.SetNumberOfLayers(2)
        window.SetSize(int(size_px[0]), int(size_px[1]))
        self.renderer = vtkRenderer()
        self.renderer.SetLayer(0)
        self.renderer.AutomaticLightCreationOff()
        for light in _light_kit():
            self.renderer.AddLight(light)
        window.AddRenderer(self.renderer)
        self.marker = vtkRenderer()  # the orientation cube, drawn over the scene's corner
        self.marker.SetLayer(1)
        self.marker.SetViewport(0.0, 0.0, MARKER_SIZE, MARKER_SIZE)
        self.marker.InteractiveOff()
        window.AddRenderer(self.marker)
        self.actors: dict[str, Any] = {}
        self.set_background(BACKGROUND_DEFAULT)

    # ------------------------------------------------------------------ props
    def set_background(
        self, color: str | Sequence[float], top: str | Sequence[float] | None = None
    ) -> None:
        """A flat background, or a gradient from ``color`` (bottom) to ``top``."""
        self.renderer.SetBackground(*parse_colour(color))
        if top is None:
            self.renderer.GradientBackgroundOff()
        else:
            self.renderer.SetBackground2(*parse_colour(top))
            self.renderer.GradientBackgroundOn()

    def add_actor(self, actor: Any, *, name: str) -> Any:
        """Show ``actor`` as ``name`` (one of that name already shown is removed)."""
        old = self.actors.pop(name, None)
        if old is not None and old is not actor:
            self.renderer.RemoveViewProp(old)
        self.renderer.AddViewProp(actor)
        self.actors[name] = actor
        return actor

    def remove_actor(self, actor: Any) -> None:
        """Stop showing ``actor`` (its GPU buffers go with it)."""
        self.renderer.RemoveViewProp(actor)
        for name in [n for n, a in self.actors.items() if a is actor]:
            del self.actors[name]

    def add_mesh(
        self,
        mesh: Any,
        *,
        name: str,
        color: Sequence[float] = (1.0, 1.0, 1.0),
        opacity: float = 1.0,
        specular: float = 0.0,
        smooth_shading: bool = False,
    ) -> Any:
        """Show the ``vtkPolyData`` ``mesh`` in one colour as ``name``; ``smooth_shading``
        interpolates normals computed for it (a mesh that has them keeps its own)."""
        if smooth_shading and mesh.GetPointData().GetNormals() is None:
            from vtkmodules.vtkFiltersCore import vtkPolyDataNormals

            normals = vtkPolyDataNormals()
            normals.SetInputData(mesh)
            normals.ComputeCellNormalsOff()  # sharp edges (> 30 degrees) split, as pyvista's
            normals.Update()
            mesh = normals.GetOutput()
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(mesh)
        mapper.ScalarVisibilityOff()
        actor = vtkActor()
        actor.SetMapper(mapper)
        prop = actor.GetProperty()
        prop.SetColor(*parse_colour(color))
        prop.SetOpacity(float(opacity))
        prop.SetSpecular(float(specular))
        prop.SetSpecularPower(SPECULAR_POWER)
        if smooth_shading:
            prop.SetInterpolationToPhong()
        else:
            prop.SetInterpolationToFlat()
        return self.add_actor(actor, name=name)

    def add_point_labels(
        self,
        points_lps: np.ndarray,
        labels: Sequence[str],
        *,
        name: str,
        font_size: int = 14,
        text_color: Sequence[float] = (1.0, 1.0, 1.0),
    ) -> Any:
        """Text ``labels`` at ``points_lps`` (N, 3), drawn over everything (never hidden)."""
        from vtkmodules.util.numpy_support import numpy_to_vtk
        from vtkmodules.vtkCommonCore import vtkPoints, vtkStringArray
        from vtkmodules.vtkCommonDataModel import vtkPolyData
        from vtkmodules.vtkRenderingCore import vtkActor2D
        from vtkmodules.vtkRenderingLabel import vtkLabeledDataMapper

        pts = vtkPoints()
        pts.SetData(numpy_to_vtk(np.ascontiguousarray(points_lps, dtype=np.float64), deep=True))
        text = vtkStringArray()
        text.SetName("labels")
        for label in labels:
            text.InsertNextValue(str(label))
        poly = vtkPolyData()
        poly.SetPoints(pts)
        poly.GetPointData().AddArray(text)
        mapper = vtkLabeledDataMapper()
        mapper.SetInputData(poly)
        mapper.SetLabelModeToLabelFieldData()
        mapper.SetFieldDataName("labels")
        prop = mapper.GetLabelTextProperty()
        prop.SetFontSize(int(font_size))
        prop.SetColor(*parse_colour(text_color))
        prop.ShadowOff()
        prop.BoldOn()
        actor = vtkActor2D()
        actor.SetMapper(mapper)
        return self.add_actor(actor, name=name)

    def clear(self) -> None:
        """Remove every named prop."""
        for actor in self.actors.values():
            self.renderer.RemoveViewProp(actor)
        self.actors = {}

    def unlit(self) -> None:
        """Remove the lights: every surface in its flat colour (the report's images)."""
        self.renderer.RemoveAllLights()

    def set_marker(self, actor: Any) -> None:
        """Show ``actor`` (the orientation cube) in the lower-left corner, turned as the scene."""
        self.marker.RemoveAllViewProps()
        self.marker.AddViewProp(actor)

    # ------------------------------------------------------------------ camera and frames
    @property
    def camera_position(self) -> list[tuple[float, float, float]]:
        """``[position, focal point, view up]`` of the camera, LPS mm."""
        cam = self.renderer.GetActiveCamera()
        return [cam.GetPosition(), cam.GetFocalPoint(), cam.GetViewUp()]

    def set_size(self, size_px: tuple[int, int]) -> None:
        """Frames of ``size_px`` (width, height) pixels from now on."""
        w, h = max(int(size_px[0]), 1), max(int(size_px[1]), 1)
        if tuple(self.window.GetSize()) != (w, h):
            self.window.SetSize(w, h)

    def _turn_marker(self) -> None:
        if self.marker.GetViewProps().GetNumberOfItems() == 0:
            return
        cam = self.renderer.GetActiveCamera()
        view = np.subtract(cam.GetPosition(), cam.GetFocalPoint())
        norm = float(np.linalg.norm(view))
        if norm == 0.0:
            return
        mc = self.marker.GetActiveCamera()
        mc.SetFocalPoint(0.0, 0.0, 0.0)
        mc.SetPosition(*(view / norm * 5.0).tolist())
        mc.SetViewUp(*cam.GetViewUp())
        self.marker.ResetCamera()

    def render(self) -> None:
        """Draw one frame (the clipping range fitted to what is shown)."""
        self.renderer.ResetCameraClippingRange()
        self._turn_marker()
        self.window.Render()

    def rgba(self) -> np.ndarray:
        """The last frame, (height, width, 4) uint8, row 0 at the top (a copy)."""
        w, h = self.window.GetSize()
        arr = vtkUnsignedCharArray()
        front = 0 if self.window.GetOffScreenRendering() else 1
        self.window.GetRGBACharPixelData(0, 0, w - 1, h - 1, front, arr, 0)
        img = vtk_to_numpy(arr).reshape(h, w, 4)
        return np.ascontiguousarray(img[::-1])

    def screenshot(self) -> np.ndarray:
        """Draw a frame and return it, (height, width, 3) uint8 RGB."""
        self.render()
        return np.ascontiguousarray(self.rgba()[..., :3])

    def close(self) -> None:
        """Release the props and the render window (from the thread that made it)."""
        self.clear()
        self.marker.RemoveAllViewProps()
        self.window.Finalize()


def _light_kit() -> list[Any]:
    """A head light and VTK's light kit (key, fill and two back lights, following the
    camera), at the intensities pyvista gives them (the scene's colours were chosen under
    them)."""
    from vtkmodules.vtkRenderingCore import vtkLight

    lights = []
    head = vtkLight()
    head.SetLightTypeToHeadlight()
    head.SetIntensity(0.25)
    lights.append(head)
    for intensity, position in _KIT:
        light = vtkLight()
        light.SetLightTypeToCameraLight()
        light.SetPosition(*position)
        light.SetFocalPoint(0.0, 0.0, 0.0)
        light.SetIntensity(intensity)
        lights.append(light)
    return lights


#: Camera lights of the light kit: (intensity, position in the camera's frame).
_KIT = (
    (0.75, (0.11161889704894966, 0.766044443118978, 0.6330222215594891)),
    (0.25, (-0.044943455527547777, -0.9659258262890683, 0.25488700224417876)),
    (0.21428571428571427, (0.9396926207859084, 0.0, -0.3420201433256687)),
    (0.21428571428571427, (-0.9396926207859084, 0.0, -0.3420201433256687)),
)

#: The stage's background before the scene sets its own.
BACKGROUND_DEFAULT = (0.0, 0.0, 0.0)
