"""The depth plots (HU, force, clearance) as a view of the document: redrawn when a path result
arrives or fails, with the rehearsal's live depth as a cursor (drawing:
:mod:`ctdrill.app.gui.plots`)."""

from __future__ import annotations

from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtGui import QResizeEvent

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.plots import WINDOW_DPI, draw_depth_plots, fit_margins, set_live_depth
from ctdrill.app.gui.results import PathView
from ctdrill.imaging.plan.types import Plan

#: What the plots say before there is anything to plot.
NO_SERIES = "open a DICOM folder"
NO_TRAJECTORY = (
    "no trajectory yet: right-click the target on a slice view, Shift+right-click the entry"
)


class PlotsView(FigureCanvasQTAgg):
    """HU, force and clearance along the drill."""

    def __init__(self, ctx: ViewContext) -> None:
        fig = Figure(figsize=(6, 4), dpi=WINDOW_DPI)
        super().__init__(fig)
        self.plot_fig = fig
        self.ctx = ctx
        draw_depth_plots(self.plot_fig, None, message=NO_SERIES)
        ctx.doc.path_changed.connect(self._path)
        ctx.doc.plan_changed.connect(self._plan)
        ctx.doc.volume_changed.connect(lambda _v: self._plan(ctx.doc.plan))
        ctx.doc.live_depth_changed.connect(self._live_depth)

    def resizeEvent(self, event: QResizeEvent) -> None:
        """Keep the labels' room in pixels whatever the size (:func:`fit_margins`)."""
        super().resizeEvent(event)
        fit_margins(self.plot_fig)

    def _plan(self, plan: Plan | None) -> None:
        if plan is None and self.ctx.doc.volume is not None:
            draw_depth_plots(self.plot_fig, None, message=NO_TRAJECTORY)
            self.draw_idle()

    def _path(self, view: PathView | None) -> None:
        doc = self.ctx.doc
        if view is None:
            if doc.path_error:  # nothing computed for this plan: say why, draw nothing old
                draw_depth_plots(self.plot_fig, None, message=f"no force profile: {doc.path_error}")
                self.draw_idle()
            return

        def show() -> None:
            if doc.path is view:
                draw_depth_plots(self.plot_fig, view.curves)
                self.ctx.steps.push(self.draw)  # ~50 ms of Agg: a pass of its own

        self.ctx.steps.push(show)

    def _live_depth(self, depth_mm: float) -> None:
        set_live_depth(self.plot_fig, depth_mm)
        self.draw_idle()
