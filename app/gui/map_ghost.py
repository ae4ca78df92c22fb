"""The outline of a dragged trajectory (the **ghost**) painted with ``QPainter`` over a
canvas' image: :class:`GhostCanvas`, the base of :class:`~ctdrill.app.gui.map_canvas.MapCanvas`.

:meth:`GhostCanvas.show_ghost_of` only records the dragged plan and asks for a paint of the
axes; the paint computes its outline (:meth:`GhostCanvas.draw_ghost_of`) and draws it over the
canvas' bitmap, which the ghost never enters (no copy of the image to restore, no matplotlib
drawing per move), so the outline is computed at most once per repaint, for the newest plan,
however many moves came.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor, QPainter, QPaintEvent, QPen

from ctdrill.app.gui.implant_drag import grips_lps
from ctdrill.app.gui.polylines import polyline
from ctdrill.imaging.plan.types import Plan

GHOST_COLOUR = "#ffffff"
#: The grips' rings: radius and line width, px.
GRIP_RADIUS_PX = 4.5
GRIP_PEN_PX = 2.0


class PlaneMap(Protocol):
    """Image millimetres (uv) <-> LPS of one view's image."""

    def to_lps(self, uv_mm: np.ndarray) -> np.ndarray:
        """(..., 2) uv mm -> (..., 3) LPS mm on the image's surface (NaN off it)."""
        ...

    def to_uv(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(..., 3) LPS -> (..., 2) uv mm and (...) offset from the surface, mm."""
        ...


class GhostCanvas(FigureCanvasQTAgg):
    """A canvas with axes :attr:`ax` mapped to LPS by :attr:`plane_map` that paints a dragged
    plan's outline (:meth:`ghost_lines`, given by subclasses) over its image."""

    ax: Any

    def __init__(self, figure: Any) -> None:
        super().__init__(figure)
        self.plane_map: PlaneMap | None = None
        #: The ghost painted: every outline NaN-joined, (M, 2) uv mm, and the grips, (K, 2)
        #: uv mm; None: no ghost.
        self._ghost: tuple[np.ndarray, np.ndarray] | None = None
        #: The plan whose ghost the next paint computes (:meth:`show_ghost_of`).
        self._ghost_plan: Plan | None = None

    def ghost_lines(self, plan: Plan) -> list[np.ndarray]:
        """The outline of ``plan``'s drill and implant on this image, (M, 2) uv mm each."""
        return []

    @property
    def ghost_uv(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The ghost painted: outlines (NaN between them) and grips, uv mm; None: none."""
        return self._ghost

    def show_ghost_of(self, plan: Plan) -> None:
        """Show ``plan`` (a dragged trajectory) as a ghost with its grips: computed and drawn
        by the next paint (a newer plan before it replaces this one)."""
        if self.plane_map is None:
            return
        self._ghost_plan = plan
        self._update_axes()

    def draw_ghost_of(self, plan: Plan) -> None:
        """Compute ``plan``'s ghost (the paint draws it)."""
        if self.plane_map is None:
            return
        points = {}
        for name, pt in grips_lps(plan).items():
            uv, _off = self.plane_map.to_uv(np.asarray(pt).reshape(1, 3))
            if np.all(np.isfinite(uv)):
                points[name] = uv[0]
        self._set_ghost(self.ghost_lines(plan), points)

    def paintEvent(self, event: QPaintEvent) -> None:
        """Compute the pending ghost (the latest dragged plan's), paint the image, then the
        ghost over it."""
        plan, self._ghost_plan = self._ghost_plan, None
        if plan is not None:
            self.draw_ghost_of(plan)
        super().paintEvent(event)
        if self._ghost is not None and hasattr(self, "renderer"):
            self._paint_ghost(*self._ghost)

    def show_ghost(self, lines_uv: list[np.ndarray], points_uv: dict[str, np.ndarray]) -> None:
        """Show a ghost of ``lines_uv`` outlines and ``points_uv`` markers at the next paint."""
        self._set_ghost(lines_uv, points_uv)
        self._update_axes()

    def _set_ghost(self, lines_uv: list[np.ndarray], points_uv: dict[str, np.ndarray]) -> None:
        gap = np.full((1, 2), np.nan)
        pieces = [part for line in lines_uv for part in (np.asarray(line, float), gap)]
        outline = np.concatenate(pieces) if pieces else np.empty((0, 2))
        grips = np.array(list(points_uv.values()), float).reshape(-1, 2)
        self._ghost = (outline, grips)

    def _to_widget(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) uv mm -> widget x, y px (Qt's: y down)."""
        if uv.shape[0] == 0:
            return np.empty(0), np.empty(0)
        xy = np.asarray(self.ax.transData.transform(uv), dtype=np.float64)
        ratio = float(self.device_pixel_ratio)
        return xy[:, 0] / ratio, self.height() - xy[:, 1] / ratio

    def _paint_ghost(self, outline: np.ndarray, grips: np.ndarray) -> None:
        """The ghost in the axes' rectangle: the outline a white line, the grips rings."""
        painter = QPainter(self)
        try:
            ratio = float(self.device_pixel_ratio)
            x0, y0, x1, y1 = (float(v) / ratio for v in self.ax.bbox.extents)
            painter.setClipRect(QRectF(x0, self.height() - y1, x1 - x0, y1 - y0))
            painter.setRenderHint(QPainter.RenderHint.Antialiasing, True)
            painter.setPen(QPen(QColor(GHOST_COLOUR), 1.0))
            x, y = self._to_widget(outline)
            polyline(painter, x, y, bold=True)
            painter.setPen(QPen(QColor(GHOST_COLOUR), GRIP_PEN_PX))
            painter.setBrush(Qt.BrushStyle.NoBrush)
            for gx, gy in zip(*self._to_widget(grips), strict=True):
                painter.drawEllipse(QPointF(gx, gy), GRIP_RADIUS_PX, GRIP_RADIUS_PX)
        finally:
            painter.end()

    def _update_axes(self) -> None:
        """Ask for a paint of the axes' region."""
        ratio = self.devicePixelRatioF()
        x0, y0, x1, y1 = self.ax.bbox.extents / ratio
        top = self.height() - y1
        self.update(int(x0) - 1, int(top) - 1, int(x1 - x0) + 3, int(y1 - y0) + 3)

    def end_ghost(self) -> None:
        """Remove the ghost (the next paint shows the plan as it is)."""
        self._ghost_plan = None
        if self._ghost is not None:
            self._ghost = None
            self._update_axes()
