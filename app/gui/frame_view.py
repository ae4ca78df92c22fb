"""A plain ``QWidget`` showing the frames of a :class:`~ctdrill.app.gui.render_thread.RenderThread`
(no OpenGL widget: Qt composes the window without OpenGL), scaled to the widget on a resize
until the next frame, drawn at the widget's size in device pixels, comes. The mouse moves the
camera (:mod:`ctdrill.app.gui.interactor`): the left button turns it, the middle button (or
shift + left) pans, the right button and the wheel zoom, R or a double click resets it."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from PySide6.QtCore import QCoreApplication, QEventLoop, QPoint, QRect, Qt
from PySide6.QtGui import QColor, QImage, QKeyEvent, QMouseEvent, QPainter, QPaintEvent, QWheelEvent
from PySide6.QtWidgets import QWidget

from ctdrill.app.gui import interactor
from ctdrill.app.gui.camera import CameraPose
from ctdrill.app.gui.render_thread import Frame, RenderThread

#: Longest wait for the frame a screenshot asks for, s.
GRAB_TIMEOUT_S = 30.0


class FrameView(QWidget):
    """Frames of a render thread on the screen, and the mouse as camera moves.

    :attr:`busy` is True while something sent to the render thread is not on the screen yet;
    :attr:`frames_drawn`, :attr:`last_frame_s` (perf_counter() when the latest frame reached
    the view) and :attr:`last_render_s` (its render, on the render thread, s) count and time
    the frames.

    Parameters
    ----------
    background : the colour shown before the first frame (``#rrggbb``).
    threaded : render on a thread of the view's own (False: on the UI thread).
    """

    def __init__(self, *, background: str = "#000000", threaded: bool = True) -> None:
        super().__init__()
        self.setFocusPolicy(Qt.FocusPolicy.ClickFocus)
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent)
        self.setMinimumSize(64, 64)
        self._background = QColor(background)
        self.rt = RenderThread(threaded=threaded)
        self.rt.frame_ready.connect(self._on_frame)
        self._image: QImage | None = None
        self._shown_seq = 0
        #: The camera of the frames (the UI thread's; sent to the render thread).
        self.camera: CameraPose | None = None
        self._drag: tuple[Qt.MouseButton, QPoint, CameraPose, bool] | None = None
        self.frames_drawn = 0
        self.last_frame_s = float("nan")  # perf_counter() when the latest frame arrived
        self.last_render_s = float("nan")  # duration of the latest frame, on the render thread

    # ------------------------------------------------------------------ frames
    @property
    def busy(self) -> bool:
        """A scene change or frame sent to the render thread is not on the screen yet."""
        return self._shown_seq < self.rt.seq

    @property
    def camera_position(self) -> list[tuple[float, ...]]:
        """``[position, focal point, view up]`` of the camera (empty: none yet)."""
        pose = self.camera
        if pose is None:
            return []
        return [tuple(float(x) for x in v) for v in (pose.position_lps, pose.focal_lps, pose.up)]

    def _on_frame(self, frame: Frame) -> None:
        if frame.image is not None:
            self._image = frame.image
            self.frames_drawn += 1
            self.last_frame_s = time.perf_counter()
            self.last_render_s = frame.render_s
            self.update()
        self._shown_seq = max(self._shown_seq, frame.seq)
        for then, result in frame.done:
            then(result)

    def paintEvent(self, event: QPaintEvent) -> None:
        painter = QPainter(self)
        try:
            rect = self.rect()
            image = self._image
            if image is None:
                painter.fillRect(rect, self._background)
                return
            dpr = self.devicePixelRatioF()
            if image.width() == round(rect.width() * dpr) and image.height() == round(
                rect.height() * dpr
            ):
                image.setDevicePixelRatio(dpr)
                painter.drawImage(QPoint(0, 0), image)
            else:  # resized: the last frame scaled until the next one comes
                painter.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform, False)
                painter.drawImage(QRect(rect), image)
        finally:
            painter.end()

    def resizeEvent(self, event: Any) -> None:
        super().resizeEvent(event)
        dpr = self.devicePixelRatioF()
        self.rt.set_size((round(self.width() * dpr), round(self.height() * dpr)))

    def render_now(self) -> None:
        """Ask the render thread for a frame (it shows every change sent before)."""
        self.rt.submit(None, key="frame")

    def set_camera(self, pose: CameraPose) -> None:
        """Draw from ``pose`` (sent to the render thread; the latest wins)."""
        self.camera = pose
        self.rt.set_camera(pose)

    def grab_rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the view's latest frame, once every change sent before is
        drawn (the caller waits, serving the frame's event)."""
        end = time.perf_counter() + GRAB_TIMEOUT_S
        app = QCoreApplication.instance()
        while self.busy and time.perf_counter() < end and app is not None:
            app.processEvents(QEventLoop.ProcessEventsFlag.ExcludeUserInputEvents, 20)
            if self.busy:
                time.sleep(0.002)
        image = self._image
        if image is None:
            return np.zeros((max(self.height(), 1), max(self.width(), 1), 3), dtype=np.uint8)
        from ctdrill.app.gui.screenshot import qimage_to_rgb

        return qimage_to_rgb(image)

    def close_plotter(self) -> None:
        """Stop the render thread (its render window released on it); call before the widget
        is destroyed."""
        self.rt.stop()

    # ------------------------------------------------------------------ mouse
    def mousePressEvent(self, event: QMouseEvent) -> None:
        if self.camera is None:
            return
        shift = bool(event.modifiers() & Qt.KeyboardModifier.ShiftModifier)
        self._drag = (event.button(), event.position().toPoint(), self.camera, shift)

    def mouseMoveEvent(self, event: QMouseEvent) -> None:
        if self._drag is None:
            return
        button, start, pose, shift = self._drag
        d = event.position().toPoint() - start
        dx, dy = float(d.x()), float(d.y())
        if button == Qt.MouseButton.LeftButton and not shift:
            moved = interactor.orbit(pose, dx, dy, (self.width(), self.height()))
        elif button in (Qt.MouseButton.MiddleButton, Qt.MouseButton.LeftButton):
            moved = interactor.pan(pose, dx, dy, self.height())
        elif button == Qt.MouseButton.RightButton:
            moved = interactor.dolly(pose, interactor.drag_zoom_factor(dy))
        else:
            return
        self.set_camera(moved)

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:
        self._drag = None

    def mouseDoubleClickEvent(self, event: QMouseEvent) -> None:
        self.reset_camera()

    def wheelEvent(self, event: QWheelEvent) -> None:
        if self.camera is not None:
            factor = interactor.wheel_factor(event.angleDelta().y())
            self.set_camera(interactor.dolly(self.camera, factor))

    def keyPressEvent(self, event: QKeyEvent) -> None:
        if event.key() == Qt.Key.Key_R:
            self.reset_camera()
        else:
            super().keyPressEvent(event)

    def reset_camera(self) -> None:
        """Put the camera back where the view starts (the subclass knows where)."""
