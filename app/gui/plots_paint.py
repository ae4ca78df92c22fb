"""The depth plots painted with ``QPainter`` (where things go: :mod:`ctdrill.app.gui.plots`).

Two layers: :func:`paint_axes` draws what stays while a plan is dragged (frames, Misch bands,
grid, ticks and their labels, axis labels, the force title, the margin line, or a message) and
the window keeps it as a pixmap; :func:`paint_curves` draws the curves, the stop and planned
marks and the stop in words over it, a millisecond or two for a few hundred points.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QBrush, QColor, QFont, QPainter, QPen

from ctdrill.app.gui.plots import (
    BAND_COLOURS,
    COLOURS,
    MISCH_BANDS,
    TEXT_PX,
    TICK_SPACING_PX,
    TITLE_PX,
    DepthCurves,
    Frame,
    PlotLayout,
    force_title,
    stop_title,
)
from ctdrill.app.gui.polylines import polygon, polyline, runs
from ctdrill.app.raster_plot import nice_ticks

#: Tick mark length, px.
TICK_PX = 4.0


def _fill(p: QPainter, x: np.ndarray, lo: np.ndarray, hi: np.ndarray, colour: QColor) -> None:
    """Fill between the rows ``lo`` and ``hi`` (px) along ``x`` (not antialiased: a tenth of
    the time, and a translucent band's edge needs none)."""
    hint = QPainter.RenderHint.Antialiasing
    smooth = p.testRenderHint(hint)
    p.setRenderHint(hint, False)
    p.setPen(Qt.PenStyle.NoPen)
    p.setBrush(QBrush(colour))
    for a, b in runs(np.isfinite(lo) & np.isfinite(hi)):
        if b - a >= 2:
            xs = np.concatenate([x[a:b], x[a:b][::-1]])
            p.drawPolygon(polygon(xs, np.concatenate([lo[a:b], hi[a:b][::-1]])))
    p.setBrush(Qt.BrushStyle.NoBrush)
    p.setRenderHint(hint, smooth)


def _colour(role: str, alpha: float = 1.0) -> QColor:
    c = QColor(COLOURS[role])
    c.setAlphaF(alpha)
    return c


def _font(px: int) -> QFont:
    font = QFont()
    font.setPixelSize(px)
    return font


def _labels(ticks: np.ndarray, decimals: int) -> list[str]:
    return [f"{v:.{decimals}f}" for v in ticks]


def _rect(f: Frame) -> QRectF:
    return QRectF(f.x0, f.y0, f.x1 - f.x0, f.y1 - f.y0)


def paint_axes(
    p: QPainter,
    layout: PlotLayout,
    curves: DepthCurves | None,
    message: str = "",
) -> None:
    """The plots' lasting layer on a white ground: frames, Misch bands, grid, ticks, labels,
    the force title and the margin (with ``curves``), or ``message`` on empty axes."""
    p.fillRect(QRectF(0, 0, layout.width, layout.height), QColor("white"))
    f_hu, f_force, f_clear = layout.frames
    text = _font(TEXT_PX)
    p.setFont(text)
    metrics = p.fontMetrics()
    # Misch bands and their names (where a band is tall enough for its name)
    p.save()
    p.setClipRect(_rect(f_hu))
    for (_label, lo, hi), colour in zip(MISCH_BANDS, BAND_COLOURS, strict=True):
        a, b = max(lo, f_hu.lo), min(hi, f_hu.hi)
        if b <= a:
            continue
        y_top, y_bottom = float(f_hu.y_px(b)), float(f_hu.y_px(a))
        band = QColor(colour)
        band.setAlphaF(0.8)
        p.fillRect(QRectF(f_hu.x0, y_top, f_hu.x1 - f_hu.x0, y_bottom - y_top), band)
    p.restore()
    p.setPen(_colour("text"))
    for label, lo, hi in MISCH_BANDS:
        a, b = max(lo, f_hu.lo), min(hi, f_hu.hi)
        if b > a and float(f_hu.y_px(a) - f_hu.y_px(b)) >= TEXT_PX:
            y = float(f_hu.y_px((a + b) / 2.0))
            p.drawText(QPointF(f_hu.x1 + 3.0, y + metrics.ascent() / 2.0 - 1.0), label)
    # grid, frames, ticks
    depth_ticks, depth_decimals = nice_ticks(
        0.0, layout.depth_max, max(1, int((f_hu.x1 - f_hu.x0) / TICK_SPACING_PX["x"]))
    )
    xs = layout.x_px(depth_ticks)
    for frame in layout.frames:
        y_ticks, decimals = nice_ticks(
            frame.lo, frame.hi, max(1, int((frame.y1 - frame.y0) / TICK_SPACING_PX["y"]))
        )
        ys = frame.y_px(y_ticks)
        p.setPen(QPen(_colour("grid"), 1.0))
        for x in xs:
            p.drawLine(QPointF(x, frame.y0), QPointF(x, frame.y1))
        for y in ys:
            p.drawLine(QPointF(frame.x0, y), QPointF(frame.x1, y))
        p.setPen(QPen(_colour("text"), 1.0))
        p.drawRect(_rect(frame))
        for y, label in zip(ys, _labels(y_ticks, decimals), strict=True):
            p.drawLine(QPointF(frame.x0 - TICK_PX, y), QPointF(frame.x0, y))
            w = metrics.horizontalAdvance(label)
            p.drawText(QPointF(frame.x0 - TICK_PX - 2.0 - w, y + metrics.ascent() / 2.0 - 1), label)
        for x in xs:
            p.drawLine(QPointF(x, frame.y1), QPointF(x, frame.y1 + TICK_PX))
    for x, label in zip(xs, _labels(depth_ticks, depth_decimals), strict=True):
        w = metrics.horizontalAdvance(label)
        p.drawText(QPointF(x - w / 2.0, f_clear.y1 + TICK_PX + 1.0 + metrics.ascent()), label)
    # axis labels
    x_label = "depth (mm)"
    p.drawText(
        QPointF(
            (f_clear.x0 + f_clear.x1 - metrics.horizontalAdvance(x_label)) / 2.0,
            f_clear.y1 + TICK_PX + 3.0 + metrics.height() + metrics.ascent(),
        ),
        x_label,
    )
    for frame, name in zip(layout.frames, ("HU", "force (N)", "clearance (mm)"), strict=True):
        p.save()
        p.translate(metrics.ascent() + 2.0, (frame.y0 + frame.y1) / 2.0)
        p.rotate(-90.0)
        p.drawText(QPointF(-metrics.horizontalAdvance(name) / 2.0, 0.0), name)
        p.restore()
    if curves is None or curves.depth_mm.size == 0:
        p.drawText(
            _rect(f_force).adjusted(6, 2, -6, -2),
            int(Qt.AlignmentFlag.AlignCenter | Qt.TextFlag.TextWordWrap),
            message or "no plan",
        )
        return
    p.setFont(_font(TITLE_PX))
    p.drawText(QPointF(f_force.x0, f_force.y0 - 5.0), force_title(curves))
    p.setFont(text)
    if not np.isfinite(curves.clearance_mm).any():
        p.drawText(_rect(f_clear), int(Qt.AlignmentFlag.AlignCenter), "no landmarks")
        return
    y = float(f_clear.y_px(curves.margin_mm))
    if f_clear.y0 <= y <= f_clear.y1:
        p.setPen(QPen(_colour("margin_line"), 1.0, Qt.PenStyle.DashLine))
        p.drawLine(QPointF(f_clear.x0, y), QPointF(f_clear.x1, y))
        p.setPen(_colour("margin_line"))
        p.drawText(QPointF(f_clear.x0 + 3.0, y - 3.0), f"margin {curves.margin_mm:g} mm")


def paint_curves(p: QPainter, layout: PlotLayout, curves: DepthCurves) -> None:
    """The curves' layer: bands, curves, the stop (solid) and the planned depth beyond it
    (dotted, shaded between) on every axes, and the stop in words above the HU plot."""
    f_hu, f_force, f_clear = layout.frames
    x = layout.x_px(curves.depth_mm)
    p.setRenderHint(QPainter.RenderHint.Antialiasing, True)
    p.save()
    p.setClipRect(_rect(f_force))
    if curves.force_band_n is not None:
        band = curves.force_band_n
        lo, hi = f_force.y_px(curves.force_n - band), f_force.y_px(curves.force_n + band)
        _fill(p, x, lo, hi, _colour("force_band", 0.25))
    if curves.mean_lo_n is not None and curves.mean_hi_n is not None:
        lo, hi = f_force.y_px(curves.mean_lo_n), f_force.y_px(curves.mean_hi_n)
        _fill(p, x, lo, hi, _colour("mean", 0.18))
        p.setPen(QPen(_colour("mean"), 1.0, Qt.PenStyle.DashLine))
        polyline(p, x, lo)
        polyline(p, x, hi)
    p.setPen(QPen(_colour("force"), 1.0))
    polyline(p, x, f_force.y_px(curves.force_n), bold=True)
    p.setClipRect(_rect(f_hu))
    p.setPen(QPen(_colour("hu"), 1.0))
    polyline(p, x, f_hu.y_px(curves.hu), bold=True)
    p.setClipRect(_rect(f_clear))
    p.setPen(QPen(_colour("clearance"), 1.0))
    polyline(p, x, f_clear.y_px(curves.clearance_mm), bold=True)
    p.restore()
    p.setRenderHint(QPainter.RenderHint.Antialiasing, False)
    stop, planned = layout.x_px(np.array([curves.stop_depth_mm, curves.planned_depth_mm]))
    beyond = curves.planned_depth_mm > curves.stop_depth_mm + 1e-6
    for frame in layout.frames:
        p.save()
        p.setClipRect(_rect(frame))
        if beyond:
            p.fillRect(QRectF(stop, frame.y0, planned - stop, frame.y1 - frame.y0),
                       _colour("stop", 0.08))  # fmt: skip
            p.setPen(QPen(_colour("planned"), 1.0, Qt.PenStyle.DotLine))
            p.drawLine(QPointF(planned, frame.y0), QPointF(planned, frame.y1))
        p.setPen(QPen(_colour("stop"), 2.0))
        p.drawLine(QPointF(stop, frame.y0), QPointF(stop, frame.y1))
        p.restore()
    title = stop_title(curves)
    p.setFont(_font(TITLE_PX))
    metrics = p.fontMetrics()
    box = QRectF(f_hu.x0, f_hu.y0 - metrics.height() - 4.0, metrics.horizontalAdvance(title) + 8.0,
                 metrics.height() + 2.0)  # fmt: skip
    p.fillRect(box, QColor("white"))
    p.setPen(_colour("text"))
    p.drawText(QPointF(box.x() + 1.0, box.y() + 1.0 + metrics.ascent()), title)


def paint_live_depth(p: QPainter, layout: PlotLayout, depth_mm: float) -> None:
    """The rehearsal's drill depth as a vertical cursor on every axes."""
    x = float(layout.x_px(depth_mm))
    p.setPen(QPen(_colour("live"), 2.0))
    for frame in layout.frames:
        if frame.x0 <= x <= frame.x1:
            p.drawLine(QPointF(x, frame.y0), QPointF(x, frame.y1))
