"""The depth plots (HU, force, clearance) as a view of the document: redrawn when a path result
arrives or fails, with the rehearsal's live depth as a cursor (drawing:
:mod:`ctdrill.app.gui.plots`).

While a plan is dragged (``Document.live``: ``curves_changed``) only the curves are redrawn: the
axes, ticks, bands and titles drawn last are kept as a bitmap, the curve artists get the new data
(:mod:`ctdrill.app.gui.plots_live`) and are drawn over it and copied to the screen
(matplotlib's blitting), a few milliseconds instead of a whole figure; the axes are drawn
again (with room to spare) only when the curves leave them. The stop in words is a label over
the plots (text is the slowest thing matplotlib draws).

The widget's Qt ``objectName`` is ``plot:force``; its ``stopDepthMm`` property (float, mm) is
the stop depth of the curves it shows, set by the paint that puts them on the widget, and
``stopDepthMmChanged`` is emitted each time new curves are painted (even at the same stop).
Curves of a drag are drawn by the paint that shows them: a result asks for a paint of the
axes, and that paint draws the latest result's curves (results that arrive before it replace
each other: each paint draws once, the newest), with the dragged view's outline in the same
screen update.
"""

from __future__ import annotations

from typing import Any

from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox
from PySide6.QtCore import Property, Signal
from PySide6.QtGui import QColor, QPaintEvent, QPalette, QResizeEvent

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.plots import (
    LIVE_HEADROOM,
    WINDOW_DPI,
    DepthCurves,
    curve_artists,
    draw_depth_plots,
    fit_margins,
    set_live_depth,
    stop_title,
)
from ctdrill.app.gui.plots_live import update_depth_plots
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.text_line import TextLine
from ctdrill.imaging.plan.types import Plan

#: What the plots say before there is anything to plot.
NO_SERIES = "open a DICOM folder"
NO_TRAJECTORY = (
    "no trajectory yet: right-click the target on a slice view, Shift+right-click the entry"
)


class PlotsView(FigureCanvasQTAgg):
    """HU, force and clearance along the drill."""

    stopDepthMmChanged = Signal(float)

    def __init__(self, ctx: ViewContext) -> None:
        fig = Figure(figsize=(6, 4), dpi=WINDOW_DPI)
        super().__init__(fig)
        self.mpl_disconnect(self.button_pick_id)  # no pick events (a walk of every artist)
        self.mpl_disconnect(self.scroll_pick_id)
        self.setObjectName("plot:force")
        self.plot_fig = fig
        self.ctx = ctx
        self._stop_mm = float("nan")
        self._curves: DepthCurves | None = None
        self._animated: list[Any] = []
        self._background: Any = None
        #: Curves drawn into the canvas, waiting for the paint that shows them.
        self._painting: DepthCurves | None = None
        #: A drag's latest curves, drawn by the next paint.
        self._live_pending: DepthCurves | None = None
        self._in_paint = False
        #: Curves drawn by blitting over the kept axes / by a whole redraw (for tests, bench).
        self.blits = 0
        self.full_draws = 0
        self.mpl_connect("draw_event", self._drawn)
        #: The stop in words, over the HU plot (an opaque line: a new stop repaints it alone,
        #: not the plots' bitmap under it).
        self.stop_label = TextLine("", self)
        palette = self.stop_label.palette()
        palette.setColor(QPalette.ColorRole.Window, QColor("white"))
        self.stop_label.setPalette(palette)
        self.stop_label.setContentsMargins(3, 1, 3, 1)
        self.stop_label.fit_height()
        self.stop_label.move(60, 2)
        self.stop_label.hide()
        draw_depth_plots(self.plot_fig, None, message=NO_SERIES)
        ctx.doc.path_changed.connect(self._path)
        ctx.doc.live.path_changed.connect(self._live_path)
        ctx.doc.live.curves_changed.connect(self._live_curves)
        ctx.doc.plan_changed.connect(self._plan)
        ctx.doc.volume_changed.connect(lambda _v: self._plan(ctx.doc.plan))
        ctx.doc.live_depth_changed.connect(self._live_depth)

    # ------------------------------------------------------------------ the stop depth
    def _get_stop(self) -> float:
        return self._stop_mm

    stopDepthMm = Property(float, _get_stop, notify=stopDepthMmChanged)

    @property
    def curves(self) -> DepthCurves | None:
        """The curves on the screen (None: a message)."""
        return self._curves

    def _shown(self, curves: DepthCurves | None) -> None:
        self._curves = curves
        if curves is None:
            self.stop_label.hide()
            return
        self._label(curves)
        self._stop_mm = float(curves.stop_depth_mm)
        self.stopDepthMmChanged.emit(self._stop_mm)

    def _label(self, curves: DepthCurves) -> None:
        """The stop in words (a label: unchanged text costs nothing)."""
        text = stop_title(curves)
        label = self.stop_label
        if label.text() != text:
            label.setText(text)
            # it only grows: a resize would repaint the plots' bitmap under its old rectangle
            width = label.fontMetrics().horizontalAdvance(text) + 8
            if width > label.width():
                label.resize(width, label.height())
        if self.stop_label.isHidden():
            self.stop_label.show()

    # ------------------------------------------------------------------ drawing
    def resizeEvent(self, event: QResizeEvent) -> None:
        """Keep the labels' room in pixels whatever the size (:func:`fit_margins`)."""
        super().resizeEvent(event)
        fit_margins(self.plot_fig)

    def _drawn(self, _event: object) -> None:
        """After every whole redraw: keep the bitmap without the curves, then draw them."""
        self._background = self.copy_from_bbox(self.plot_fig.bbox)
        for artist in self._animated:
            if artist.figure is not None:
                self.plot_fig.draw_artist(artist)

    def _animate(self, artists: list[Any]) -> None:
        for artist in self._animated:
            artist.set_animated(False)
        self._animated = artists
        for artist in artists:
            artist.set_animated(True)

    def show_message(self, message: str) -> None:
        """Empty axes with ``message``."""
        self._live_pending = None
        draw_depth_plots(self.plot_fig, None, message=message)
        self._animate([])
        self._shown(None)
        self.draw_idle()

    def show_curves(self, curves: DepthCurves, *, live: bool = False) -> None:
        """Draw ``curves`` now: over the kept axes when ``live`` and they fit, else whole
        (with room to spare when ``live``); then ``stopDepthMm`` says their stop."""
        self._live_pending = None
        if live and self._background is not None:
            artists = update_depth_plots(self.plot_fig, curves)
            if artists is not None:
                self._animate(artists)
                self.restore_region(self._background)
                for artist in artists:
                    self.plot_fig.draw_artist(artist)
                # the axes only (ticks and titles did not change), at the next paint
                self._update_region(Bbox.union([ax.bbox for ax in self.plot_fig.axes]))
                self.blits += 1
                self._painting = curves
                return
        headroom = LIVE_HEADROOM if live else 1.0
        draw_depth_plots(self.plot_fig, curves, headroom=headroom, title_stop=False)
        arts = curve_artists(self.plot_fig)
        self._animate([] if arts is None else arts.all())
        if live:
            self._finish(curves)
        else:  # the Agg render (~50-200 ms) in a pass of its own, next
            self.ctx.steps.push(lambda: self._finish(curves), first=True)

    def _finish(self, curves: DepthCurves) -> None:
        self.draw()
        self.full_draws += 1
        self._label(curves)
        label = self.stop_label  # the whole plot repaints: the label may shrink too
        label.resize(label.fontMetrics().horizontalAdvance(label.text()) + 8, label.height())
        self._painting = curves
        self.update()

    def _update_region(self, bbox: Bbox) -> None:
        """Ask for a paint of ``bbox`` (display pixels) with the next event-loop pass (none
        from within a paint: that paint shows it)."""
        if self._in_paint:
            return
        ratio = self.device_pixel_ratio
        x0, y0, x1, y1 = (float(v) / ratio for v in bbox.extents)
        self.update(int(x0) - 1, int(self.height() - y1) - 1, int(x1 - x0) + 3, int(y1 - y0) + 3)

    def paintEvent(self, event: QPaintEvent) -> None:
        """Draw a drag's latest curves (if any came since the last paint), paint, then say
        which curves are on the widget (``stopDepthMm``)."""
        live = self._live_pending
        if live is not None:
            self._in_paint = True
            try:
                self.show_curves(live, live=True)
            finally:
                self._in_paint = False
        super().paintEvent(event)
        curves, self._painting = self._painting, None
        if curves is not None:
            self._shown(curves)

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
            # a canvas the layout collapsed (hidden in a blind trial) has no axes to draw on;
            # the next path, once shown, draws
            if doc.path is view and self.width() > 1 and self.height() > 1:
                self.show_curves(view.curves)

        self.ctx.steps.push(show, first=True)  # before the other views' drawing steps

    def _live_path(self, view: PathView | None) -> None:
        """No path for a dragged plan: why."""
        live = self.ctx.doc.live
        if view is None and live.error:
            self.show_message(f"no force profile: {live.error}")

    def _live_curves(self, view: PathView) -> None:
        """A dragged plan's curves: at the next paint, over the kept axes."""
        if view is self.ctx.doc.live.curves:
            if self._background is None or not self.isVisible():
                self.show_curves(view.curves, live=True)
            else:  # drawn by the paint that shows it (the newest by then)
                self._live_pending = view.curves
                self._label(view.curves)  # its label painted in the same screen update
                self._update_region(Bbox.union([ax.bbox for ax in self.plot_fig.axes]))

    def _live_depth(self, depth_mm: float) -> None:
        if not self.isVisible():  # hidden (a blind trial): its axes have no size to draw in
            return
        set_live_depth(self.plot_fig, depth_mm)
        self.draw_idle()
