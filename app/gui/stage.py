"""The 3D view's stage: a VTK renderer in an off-screen render window, built from raw
``vtkmodules`` (no ``pyvista.plotting``: it costs 0.8 s to import), with the few calls the scene
needs (:mod:`ctdrill.app.gui.scene`): add a mesh or an actor by name, point labels, a gradient
background, the orientation cube in a corner viewport, the camera, a frame read into an array.

The window's 3D view owns one on its render thread (:mod:`ctdrill.app.gui.render_thread`), the
report one on the calling thread (:mod:`ctdrill.app.gui.offscreen`): both draw the same scene.

The orientation cube is drawn in a small render window of its own, only when the camera turns
(or the frame's size changes), and laid over the frame's lower-left corner when the frame is read
(:meth:`Stage.rgba`): the same pixels as a second layer of the frame's window, without its cost
(4-5 ms a frame on llvmpipe, nearly all of it fixed) in the frames a scene change draws.
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
            window = offscreen_window()
        self.window = window
        self.egl = window.GetClassName() == "vtkEGLRenderWindow"
        window.SetMultiSamples(int(multi_samples))
        window.SetSize(int(size_px[0]), int(size_px[1]))
        self.renderer = vtkRenderer()
        self.renderer.SetLayer(0)
        self.renderer.AutomaticLightCreationOff()
        for light in _light_kit():
            self.renderer.AddLight(light)
        window.AddRenderer(self.renderer)
        self.marker = vtkRenderer()  # the orientation cube, in a window of its own
        self.marker.InteractiveOff()
        self.marker.SetBackground(0.0, 0.0, 0.0)
        self.marker.SetBackgroundAlpha(0.0)
        self._marker_window: Any = None  # made with the first cube drawn
        #: The cube's last image, (h, w, 4) uint8 RGBA premultiplied, row 0 at the top, and
        #: what it was drawn for (view direction, view up, size); None: none drawn.
        self._marker_rgba: np.ndarray | None = None
        self._marker_key: tuple[float, ...] | None = None
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
        self._marker_key = None  # drawn again with the next frame

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

    def marker_size_px(self) -> tuple[int, int]:
        """(width, height) of the cube's corner, pixels: :data:`MARKER_SIZE` of the frame's,
        rounded as VTK rounds a viewport's."""
        w, h = self.window.GetSize()
        return max(int(MARKER_SIZE * w + 0.5), 1), max(int(MARKER_SIZE * h + 0.5), 1)

    def _draw_marker(self) -> None:
        """Draw the cube turned as the camera, unless its image is already of this view
        direction, view up and size."""
        if self.marker.GetViewProps().GetNumberOfItems() == 0:
            self._marker_rgba = None
            return
        cam = self.renderer.GetActiveCamera()
        view = np.subtract(cam.GetPosition(), cam.GetFocalPoint())
        norm = float(np.linalg.norm(view))
        if norm == 0.0:
            return
        size = self.marker_size_px()
        # rounded: a dolly or a pan leaves the direction but moves its last bits
        turn = np.round(np.concatenate([view / norm, cam.GetViewUp()]), 9)
        key = (*turn.tolist(), *size)
        if key == self._marker_key and self._marker_rgba is not None:
            return
        if self._marker_window is None:
            self._marker_window = _marker_window(self.egl)
            self._marker_window.AddRenderer(self.marker)
        win = self._marker_window
        if tuple(win.GetSize()) != size:
            win.SetSize(*size)
        mc = self.marker.GetActiveCamera()
        # a new cube is drawn twice: its bounds (which frame it) are its drawn ones from its
        # first frame on, so its size never changes between the first frames
        for _ in range(2 if self._marker_key is None else 1):
            mc.SetFocalPoint(0.0, 0.0, 0.0)
            mc.SetPosition(*(view / norm * 5.0).tolist())
            mc.SetViewUp(*cam.GetViewUp())
            self.marker.ResetCamera()
            win.Render()
        self._marker_rgba = _read_rgba(win)
        self._marker_key = key
        self.window.MakeCurrent()  # the frame's context again (its props are released in it)

    def render(self) -> None:
        """Draw one frame (the clipping range fitted to what is shown), and the cube if the
        camera turned."""
        self.renderer.ResetCameraClippingRange()
        self.window.Render()
        self._draw_marker()

    def rgba(self) -> np.ndarray:
        """The last frame with the cube over its lower-left corner, (height, width, 4) uint8,
        row 0 at the top (a copy)."""
        img = _read_rgba(self.window)
        cube = self._marker_rgba
        if cube is not None and cube.shape[0] <= img.shape[0] and cube.shape[1] <= img.shape[1]:
            over_premultiplied(img[img.shape[0] - cube.shape[0] :, : cube.shape[1]], cube)
        return img

    def screenshot(self) -> np.ndarray:
        """Draw a frame and return it, (height, width, 3) uint8 RGB."""
        self.render()
        return np.ascontiguousarray(self.rgba()[..., :3])

    def close(self) -> None:
        """Release the props and the render window (from the thread that made it)."""
        self.clear()
        self.marker.RemoveAllViewProps()
        if self._marker_window is not None:
            self._marker_window.Finalize()
            self._marker_window = None
        self.window.Finalize()


def offscreen_window(egl: bool = True) -> Any:
    """An off-screen render window: EGL's when ``egl`` and it can render
    (:func:`egl_render_window`), else VTK's default one."""
    win = egl_render_window() if egl else None
    if win is None:
        win = vtkRenderWindow()
        win.SetOffScreenRendering(1)
    return win


def _marker_window(egl: bool) -> Any:
    """An off-screen render window for the cube, of the frame's kind, with a transparent
    background (alpha kept) and no multisampling (as the frame's)."""
    win = offscreen_window(egl)
    win.SetMultiSamples(0)
    win.SetAlphaBitPlanes(1)
    return win


def _read_rgba(window: Any) -> np.ndarray:
    """The last frame of ``window``, (height, width, 4) uint8, row 0 at the top (a copy)."""
    w, h = window.GetSize()
    arr = vtkUnsignedCharArray()
    front = 0 if window.GetOffScreenRendering() else 1
    window.GetRGBACharPixelData(0, 0, w - 1, h - 1, front, arr, 0)
    img = vtk_to_numpy(arr).reshape(h, w, 4)
    return np.ascontiguousarray(img[::-1])


def over_premultiplied(dst: np.ndarray, src: np.ndarray) -> None:
    """Lay ``src`` (h, w, 4) uint8, its colour premultiplied by its alpha (as drawn over a
    transparent black background), over the RGB of ``dst`` (h, w, >= 3) uint8, in place:
    ``dst = src + dst * (1 - alpha)``, rounded. Where alpha is 255, ``dst`` becomes ``src``
    exactly; where it is 0, ``dst`` is unchanged."""
    alpha = src[..., 3]
    whole = alpha == 255
    dst[..., :3][whole] = src[..., :3][whole]
    part = (alpha > 0) & ~whole
    if part.any():
        keep = 1.0 - alpha[part].astype(np.float64)[:, None] / 255.0
        mixed = src[..., :3][part] + dst[..., :3][part].astype(np.float64) * keep
        dst[..., :3][part] = np.clip(np.rint(mixed), 0, 255).astype(np.uint8)


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
