"""Window screenshots that include the OpenGL content, and the pixel checks that prove a view
really drew (not blank, not black)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PySide6.QtCore import QPoint, QRect
from PySide6.QtGui import QImage, QPainter
from PySide6.QtWidgets import QWidget

#: A region counts as drawn when its grey-level standard deviation reaches this (0..255) ...
MIN_STD = 2.0
#: ... and it has at least this many distinct grey levels (what ``QWidget.grab`` returns for a
#: GL view it cannot read is a flat black or white rectangle: one level).
MIN_LEVELS = 16


@dataclass(frozen=True)
class RegionStats:
    """Pixel statistics of an image region (grey levels 0..255)."""

    mean: float
    std: float
    levels: int

    @property
    def drawn(self) -> bool:
        """True when the region shows structure rather than a flat fill."""
        return self.std >= MIN_STD and self.levels >= MIN_LEVELS


def region_stats(rgb: np.ndarray, rect: tuple[int, int, int, int] | None = None) -> RegionStats:
    """Statistics of ``rgb`` (H, W, 3) uint8 within ``rect`` = (x, y, w, h) pixels."""
    img = np.asarray(rgb)
    if rect is not None:
        x, y, w, h = rect
        img = img[max(y, 0) : y + h, max(x, 0) : x + w]
    if img.size == 0:
        return RegionStats(0.0, 0.0, 0)
    grey = img[..., :3].astype(np.float64) @ np.array([0.299, 0.587, 0.114])
    return RegionStats(
        mean=float(grey.mean()),
        std=float(grey.std()),
        levels=int(np.unique(np.rint(grey).astype(np.uint8)).size),
    )


def qimage_to_rgb(image: QImage) -> np.ndarray:
    """(H, W, 3) uint8 copy of a QImage."""
    img = image.convertToFormat(QImage.Format.Format_RGB888)
    w, h, stride = img.width(), img.height(), img.bytesPerLine()
    buf = np.frombuffer(img.constBits(), dtype=np.uint8, count=stride * h)
    return buf.reshape(h, stride)[:, : w * 3].reshape(h, w, 3).copy()


def rgb_to_qimage(rgb: np.ndarray) -> QImage:
    """A QImage (own copy) of an (H, W, 3) uint8 array."""
    arr = np.ascontiguousarray(rgb[..., :3], dtype=np.uint8)
    h, w, _ = arr.shape
    return QImage(arr.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()


def widget_rect(widget: QWidget, window: QWidget) -> QRect:
    """``widget``'s rectangle in ``window`` coordinates (logical pixels)."""
    top_left = widget.mapTo(window, QPoint(0, 0))
    return QRect(top_left, widget.size())


def grab_window(window: QWidget, gl_views: list[tuple[QWidget, np.ndarray]]) -> QImage:
    """The window as displayed, with each OpenGL view's own render pasted over its area.

    ``QWidget.grab`` misses what OpenGL drew; ``gl_views`` pairs each GL widget with an
    (H, W, 3) image of its render window, scaled to the widget's area.
    """
    shot = window.grab().toImage().convertToFormat(QImage.Format.Format_RGB888)
    ratio = shot.devicePixelRatio() or 1.0
    painter = QPainter(shot)
    try:
        for widget, rgb in gl_views:
            rect = widget_rect(widget, window)
            painter.drawImage(rect, rgb_to_qimage(rgb))
    finally:
        painter.end()
    if ratio != 1.0:
        shot.setDevicePixelRatio(ratio)
    return shot
