"""What the force plot (``plot:force``) painted, read back from its pixels: the stop's column
and the margin's row in data units (the widget's layout maps pixels to millimetres)."""

from __future__ import annotations

import numpy as np
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QWidget

from ctdrill.app.gui.plots import COLOURS, Frame, PlotLayout
from ctdrill.app.gui.screenshot import qimage_to_rgb


def rgb(role: str) -> np.ndarray:
    c = QColor(COLOURS[role])
    return np.array([c.red(), c.green(), c.blue()])


def painted(plot: QWidget) -> tuple[np.ndarray, PlotLayout]:
    """The plot's pixels (H, W, 3) as painted now, and where its axes are."""
    img = qimage_to_rgb(plot.grab().toImage())
    layout = plot.layout_px  # type: ignore[attr-defined]
    assert layout is not None
    return img, layout


def _inside(img: np.ndarray, f: Frame) -> np.ndarray:
    return img[int(f.y0) + 2 : int(f.y1) - 1, int(f.x0) + 2 : int(f.x1) - 1]


def vertical_marks_mm(img: np.ndarray, layout: PlotLayout, role: str) -> list[list[float]]:
    """Per axes, the depths (mm) of the lines of colour ``role`` spanning most of its height
    (a line 2 px wide is one mark, at its middle)."""
    out = []
    for f in layout.frames:
        area = _inside(img, f)
        share = np.all(area == rgb(role), axis=-1).mean(axis=0)
        cols = np.flatnonzero(share > 0.6)
        marks: list[float] = []
        for group in np.split(cols, np.flatnonzero(np.diff(cols) > 1) + 1) if cols.size else []:
            x = float(group.mean()) + int(f.x0) + 2 + 0.5
            marks.append(layout.depth_at(x))
        out.append(marks)
    return out


def horizontal_marks(img: np.ndarray, frame: Frame, role: str, share: float = 0.3) -> list[float]:
    """Data values of the rows of ``frame`` where colour ``role`` covers ``share`` of the width
    (a dashed line covers about half)."""
    area = _inside(img, frame)
    rows = np.flatnonzero(np.all(area == rgb(role), axis=-1).mean(axis=1) > share)
    groups = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1) if rows.size else []
    return [frame.value_at(float(g.mean()) + int(frame.y0) + 2 + 0.5) for g in groups]
