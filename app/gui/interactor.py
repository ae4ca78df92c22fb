"""The 3D view's VTK widget: pyvistaqt's ``QtInteractor`` drawing each frame once."""

from __future__ import annotations

from typing import Any

from pyvistaqt import QtInteractor


class Interactor(QtInteractor):
    """pyvistaqt's interactor with one render per frame.

    pyvistaqt renders in every ``paintGL``, also when the paint was scheduled by a render that
    just finished (the frame event of :meth:`View3D.render_now`, or of the interactor style
    turning the camera): each frame was rendered twice, twice the time the UI thread is held
    on software OpenGL. Here a paint that follows a finished render, with nothing resized in
    between, only shows (blits) that frame, as VTK's own ``QVTKOpenGLNativeWidget`` does; any
    other paint (exposed, resized) renders as before."""

    _fresh = False  # a render finished and its frame is not shown yet

    def _cb_frame(self, obj: Any, evt: Any) -> None:
        rw = self._RenderWindow
        if (
            rw is not None
            and not self._in_paint
            and not (rw.GetDoubleBuffer() and not rw.GetSwapBuffers())
        ):
            self._fresh = True
        super()._cb_frame(obj, evt)

    def resizeGL(self, w: int, h: int) -> None:
        self._fresh = False
        super().resizeGL(w, h)

    def paintGL(self) -> None:
        if not self._fresh:
            super().paintGL()
            return
        self._fresh = False
        self._in_paint = True  # pyvistaqt's paintGL then blits without rendering
        try:
            super().paintGL()
        finally:
            self._in_paint = False
