"""The depth plots (HU, force, clearance) as a view of the document: redrawn when a path result
arrives or fails, with the rehearsal's live depth as a cursor (what goes where:
:mod:`ctdrill.app.gui.plots`; the painting: :mod:`ctdrill.app.gui.plots_paint`).

A ``QWidget`` painted with ``QPainter``: the axes, ticks, bands and titles are kept as a pixmap
(painted again only when the widget's size, the axes' ranges or the titles change) and the
curves are painted over it by every paint, a millisecond or two. While a plan is dragged
(``Document.live``: ``curves_changed``) the axes keep their ranges (with room to spare) as long
as the new curves fit them.

The widget's Qt ``objectName`` is ``plot:force``; its ``stopDepthMm`` property (float, mm) is
the stop depth of the curves it shows, set by the paint that puts them on the widget, and
``stopDepthMmChanged`` is emitted each time new curves are painted (even at the same stop).
Curves of a drag are drawn by the paint that shows them: a result asks for a paint, and that
paint draws the latest result's curves (results that arrive before it replace each other:
each paint draws once, the newest). The status bar says the stop of the curves shown (of the
dragged plan during a drag, as the banner), in the words of
:func:`~ctdrill.app.gui.plots.stop_title`.
"""

from __future__ import annotations

import time
from typing import Any

from PySide6.QtCore import Property, QSize, Qt, Signal
from PySide6.QtGui import QPainter, QPaintEvent, QPixmap
from PySide6.QtWidgets import QSizePolicy, QWidget

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.plots import (
    LIVE_HEADROOM,
    DepthCurves,
    DepthLimits,
    PlotLayout,
    curves_key,
    depth_limits,
    plot_layout,
    stop_title,
)
from ctdrill.app.gui.plots_paint import paint_axes, paint_curves, paint_live_depth
from ctdrill.app.gui.results import PathView
from ctdrill.imaging.plan.types import Plan

#: What the plots say before there is anything to plot.
NO_SERIES = "open a DICOM folder"
NO_TRAJECTORY = (
    "no trajectory yet: right-click the target on a slice view, Shift+right-click the entry"
)


class PlotsView(QWidget):
    """HU, force and clearance along the drill."""

    stopDepthMmChanged = Signal(float)

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.setObjectName("plot:force")
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent)  # every pixel painted
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.ctx = ctx
        self._stop_mm = float("nan")
        #: The curves painted last (None: a message) and the message.
        self._curves: DepthCurves | None = None
        self.message = NO_SERIES
        #: Curves to paint next, and the axes' ranges they are drawn in.
        self._next: DepthCurves | None = None
        self._limits: DepthLimits | None = None
        #: A drag's latest curves, adopted by the next paint.
        self._live_pending: DepthCurves | None = None
        self._live_depth: float | None = None
        #: New curves wait for a paint (it says so: ``stopDepthMmChanged``).
        self._fresh = False
        self._dragging = False
        #: The axes' pixmap and what it was painted for.
        self._background: QPixmap | None = None
        self._background_key: tuple[Any, ...] = ()
        self._layout: PlotLayout | None = None
        #: Paints of new curves over the kept axes / with the axes painted again, and the
        #: last paint's wall and CPU time, s (for tests and the bench).
        self.blits = 0
        self.full_draws = 0
        self.paint_s = 0.0
        self.paint_cpu_s = 0.0
        ctx.doc.path_changed.connect(self._path)
        ctx.doc.live.path_changed.connect(self._live_path)
        ctx.doc.live.curves_changed.connect(self._live_curves)
        ctx.doc.plan_changed.connect(self._plan)
        ctx.doc.volume_changed.connect(lambda _v: self._plan(ctx.doc.plan))
        ctx.doc.live_depth_changed.connect(self._live_depth_changed)
        ctx.doc.live.plan_dragged.connect(self._dragged)

    def sizeHint(self) -> QSize:
        return QSize(480, 320)

    # ------------------------------------------------------------------ the stop depth
    def _get_stop(self) -> float:
        return self._stop_mm

    stopDepthMm = Property(float, _get_stop, notify=stopDepthMmChanged)

    @property
    def curves(self) -> DepthCurves | None:
        """The curves on the screen (None: a message)."""
        return self._curves

    @property
    def layout_px(self) -> PlotLayout | None:
        """Where the last paint put the axes (None: not painted yet, or too small)."""
        return self._layout

    # ------------------------------------------------------------------ what to show
    def show_message(self, message: str) -> None:
        """Empty axes with ``message``."""
        self._live_pending = None
        self._next, self._limits, self.message = None, None, message
        self._curves = None
        self.update()

    def show_curves(self, curves: DepthCurves, *, live: bool = False) -> None:
        """Show ``curves`` at the next paint, in the axes' ranges kept when ``live`` and they
        fit (with room to spare when they do not), else ranges of their own; then
        ``stopDepthMm`` says their stop."""
        self._adopt(curves, live=live)
        self.update()

    def _adopt(self, curves: DepthCurves, *, live: bool) -> None:
        """``curves`` are the next to paint (see :meth:`show_curves`)."""
        self._live_pending = None
        need = depth_limits(curves)
        same = self._next is not None and curves_key(self._next) == curves_key(curves)
        if not (live and same and self._limits is not None and self._limits.contains(need)):
            self._limits = depth_limits(curves, LIVE_HEADROOM) if live else need
        self._next, self.message, self._fresh = curves, "", True

    # ------------------------------------------------------------------ painting
    def _axes_pixmap(self, layout: PlotLayout) -> QPixmap:
        """The axes' layer for ``layout`` (painted again only when what it shows changed)."""
        curves = self._next
        key: tuple[Any, ...] = (
            layout,
            self.message,
            None if curves is None else curves_key(curves),
            self.devicePixelRatioF(),
        )
        if self._background is None or key != self._background_key:
            ratio = self.devicePixelRatioF()
            pixmap = QPixmap(round(layout.width * ratio), round(layout.height * ratio))
            pixmap.setDevicePixelRatio(ratio)
            painter = QPainter(pixmap)
            paint_axes(painter, layout, curves, self.message)
            painter.end()
            self._background, self._background_key = pixmap, key
            self.full_draws += 1
        return self._background

    def paintEvent(self, event: QPaintEvent) -> None:
        """Adopt a drag's latest curves (if any came since the last paint), paint, then say
        which curves are on the widget (``stopDepthMm``)."""
        t0, c0 = time.perf_counter(), time.thread_time()
        live = self._live_pending
        if live is not None:
            self._adopt(live, live=True)
        curves = self._next
        fresh, self._fresh = self._fresh and curves is not None, False
        layout = plot_layout(self.width(), self.height(), self._limits)
        painter = QPainter(self)
        if layout is None:
            painter.fillRect(self.rect(), Qt.GlobalColor.white)
        else:
            drawn = self.full_draws
            painter.drawPixmap(0, 0, self._axes_pixmap(layout))
            if curves is not None:
                paint_curves(painter, layout, curves)
                if fresh and self.full_draws == drawn:
                    self.blits += 1
            if self._live_depth is not None:
                paint_live_depth(painter, layout, self._live_depth)
        painter.end()
        self._layout = layout
        self._curves = curves
        self.paint_s = time.perf_counter() - t0
        self.paint_cpu_s = time.thread_time() - c0
        if fresh and curves is not None:
            self._stop_mm = float(curves.stop_depth_mm)
            self.stopDepthMmChanged.emit(self._stop_mm)

    # ------------------------------------------------------------------ document
    def _plan(self, plan: Plan | None) -> None:
        if plan is None and self.ctx.doc.volume is not None:
            self.show_message(NO_TRAJECTORY)

    def _path(self, view: PathView | None) -> None:
        doc = self.ctx.doc
        if view is None:
            if doc.path_error:  # nothing computed for this plan: say why, draw nothing old
                self.show_message(f"no force profile: {doc.path_error}")
            return

        def show() -> None:
            if doc.path is view:
                self.show_curves(view.curves)
                if not doc.live.dragging:  # a drag's status is the dragged plan's stop
                    self.ctx.status(stop_title(view.curves))

        self.ctx.steps.push(show, first=True)  # before the other views' drawing steps

    def _live_path(self, view: PathView | None) -> None:
        """No path for a dragged plan: why."""
        live = self.ctx.doc.live
        if view is None and live.error:
            self.show_message(f"no force profile: {live.error}")

    def _live_curves(self, view: PathView) -> None:
        """A dragged plan's curves: drawn by the next paint (the newest by then)."""
        if view is self.ctx.doc.live.curves:
            self._live_pending = view.curves
            self.update()
            self.ctx.status(stop_title(view.curves))  # the stop drawn next, in words

    def _dragged(self, plan: Plan | None) -> None:
        """A drag ended (released or cancelled): the status says the plan's own stop."""
        dragged, self._dragging = self._dragging, plan is not None
        path = self.ctx.doc.path
        if plan is None and dragged and path is not None:
            self.ctx.status(stop_title(path.curves))

    def _live_depth_changed(self, depth_mm: float) -> None:
        self._live_depth = depth_mm
        self.update()
