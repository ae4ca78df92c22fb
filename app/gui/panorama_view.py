"""The panoramic reformat along the dental arch and the cross-section through the implant.

A page of the main area (beside the 3D and slice views): the panorama on the left, the
cross-section on the right, each with its slab thickness and mean / MIP. The cross-section stands
perpendicular to the arch at the current trajectory's implant site, tilted to contain its axis;
the mouse wheel or the arrow keys over it (Shift or Page Up / Down: bigger steps) scroll it along
the arch, keeping the tilt; a click on either image links the views there (the crosshair:
the cross-section moves to the point, the slice views go through it), and "At implant" brings
it back. Both are computed in worker threads (:mod:`ctdrill.app.gui.reformats`, latest wins)
and drawn with :func:`ctdrill.app.reformat.draw.draw_reformat`, the figure ``ctdrill panorama``
writes: canal and margin zone, implant body, drill to its stop, scale bar. A panorama is
recomputed only when the series, the arch, its slab or its height change; plan edits redraw
the overlays. Nothing is computed while the page is hidden.

The tool row (:class:`~ctdrill.app.gui.reformat_canvas.ReformatTools`) traces canals on either
image, measures distances and angles; on the cross-section the current implant is dragged
(moved, tilted by its platform, slid along its axis with Shift) with its angulation, depth
below the crest, distance to the canal and thinnest wall read out live under the image
(:mod:`ctdrill.app.gui.readouts`).
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QShowEvent
from PySide6.QtWidgets import (
    QComboBox,
    QLabel,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.gui import reformats
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.plan_editor import PlanEditor
from ctdrill.app.gui.problems import offending_implants
from ctdrill.app.gui.readouts import ImplantReadout, readout_text
from ctdrill.app.gui.reformat_canvas import ReformatCanvas, ReformatTools, SlabControls
from ctdrill.app.gui.text_line import SteadyLabel
from ctdrill.app.gui.workers import Runner
from ctdrill.app.reformat.draw import draw_reformat
from ctdrill.app.reformat.region import PANORAMA_HEIGHT_MM, arch_region
from ctdrill.imaging.sampling.reformat import Reformat

__all__ = ["PanoramaView", "ReformatCanvas"]

#: The panorama's height choices: the arch region (default) or the scan's whole height.
HEIGHTS = ("arch region", "whole height")


class PanoramaView(QWidget):
    """Panorama beside cross-section, each computed off the UI thread."""

    #: Emitted after an image is drawn (``panorama`` or ``cross_section``), for tests.
    drawn = Signal(str)

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.pano_controls = SlabControls("Panorama", reformats.PANORAMA_SLAB_MM)
        self.cross_controls = SlabControls("Cross-section", reformats.CROSS_SLAB_MM)
        self.height_box = QComboBox()
        self.height_box.addItems(list(HEIGHTS))
        self.height_box.setToolTip(
            f"rows of the panorama: the arch region ({PANORAMA_HEIGHT_MM:g} mm "
            "around the jaw) or the scan's whole height"
        )
        self.height_box.currentIndexChanged.connect(lambda _i: self.refresh())
        self.pano_controls.row.addWidget(self.height_box)
        self.tools = ReformatTools(ctx.doc)
        #: The current implant's figures (live while it is dragged).
        # it follows a drag: a label that re-lays out the window only for a new line count
        self.readout = SteadyLabel("")
        self.readout.setToolTip(
            "tilt from the vertical (bucco-lingual B/Li and mesio-distal M/D in the arch's "
            "frame), the platform's depth below the bone crest along the axis, the distance "
            "to the nearest canal, the thinnest bone wall around the implant"
        )
        self.position = QLabel("")
        self.to_implant = QPushButton("At implant")
        self.to_implant.setToolTip("Put the cross-section back through the current implant")
        self.to_implant.clicked.connect(lambda: self.move_to(None))
        self.position.setToolTip(
            "Wheel or arrow keys over the cross-section: 1 mm along the arch (Shift, Page "
            "Up/Down: 5 mm); a click on the panorama moves it there"
        )
        self.pano_controls.row.addStretch(1)
        self.cross_controls.row.addStretch(1)
        self.cross_controls.row.addWidget(self.to_implant)
        self.pano = ReformatCanvas("view:panorama")
        self.cross = ReformatCanvas("view:cross_section")
        split = QSplitter(Qt.Orientation.Horizontal)
        for widgets in (
            (self.pano_controls, self.pano),
            (self.cross_controls, self.position, self.cross, self.readout),
        ):
            pane = QWidget()
            lay = QVBoxLayout(pane)
            lay.setContentsMargins(0, 0, 0, 0)
            for widget in widgets:
                lay.addWidget(widget, 1 if isinstance(widget, ReformatCanvas) else 0)
            split.addWidget(pane)
        split.setSizes([600, 400])
        page = QVBoxLayout(self)
        page.addWidget(self.tools)
        page.addWidget(split, 1)
        self.editor = PlanEditor(ctx)
        for canvas in (self.pano, self.cross):
            self.editor.connect(canvas)
        self.tools.mode_changed.connect(self.set_mode)
        #: Requested arc position of the cross-section (None: the current implant's site).
        self.at_arc_mm: float | None = None
        self.pano_image: Reformat | None = None
        self.cross_image: Reformat | None = None
        self._pano_req: reformats.PanoramaRequest | None = None
        self._cross_req: reformats.CrossRequest | None = None
        self._current: int | None = None
        self._dirty = True
        self._queued: set[str] = set()
        self.pano_runner = Runner(self._pano_done, self._failed(self.pano), parent=self)
        self.cross_runner = Runner(self._cross_done, self._failed(self.cross), parent=self)
        self.pano_controls.changed.connect(self.refresh)
        self.cross_controls.changed.connect(self.refresh)
        self.cross.scrolled.connect(self.scroll_along)
        doc = ctx.doc
        doc.volume_changed.connect(lambda _v: self.refresh())
        doc.plans_changed.connect(lambda _p: self.refresh())
        doc.path_changed.connect(lambda _v: self._redraw())
        doc.live.readout_changed.connect(self._show_readout)
        doc.plan_changed.connect(lambda p: self.readout.setText("") if p is None else None)
        doc.live.crosshair_changed.connect(self.go_to)
        self.pano.show_message(reformats.NO_SERIES)
        self.cross.show_message("")

    # ------------------------------------------------------------------ requests
    def showEvent(self, event: QShowEvent) -> None:
        super().showEvent(event)
        if self._dirty:
            self.refresh()

    def refresh(self) -> None:
        """Recompute what changed (series, arch, slab, the cross-section's place), or redraw
        the overlays when only the plan changed; nothing while the page is hidden."""
        if not self.isVisible():
            self._dirty = True
            return
        self._dirty = False
        doc = self.ctx.doc
        if doc.current != self._current:  # another trajectory: its implant's site
            self._current, self.at_arc_mm = doc.current, None
        arch = doc.arch_lps
        if doc.volume is None or arch is None:
            self._pano_req = self._cross_req = None
            self.pano_image = self.cross_image = None
            self.pano_runner.cancel()
            self.cross_runner.cancel()
            self.pano_controls.busy.setText("")
            self.cross_controls.busy.setText("")
            self.position.setText("")
            self.pano.show_message(reformats.NO_SERIES if doc.volume is None else reformats.NO_ARCH)
            self.cross.show_message("")
            return
        rows: tuple[float | None, float | None] = (None, None)
        if self.height_box.currentIndex() == 0:
            rows = arch_region(doc.volume, arch, doc.plans)
        pano = reformats.PanoramaRequest(
            doc.volume, arch, self.pano_controls.slab_mm, self.pano_controls.slab_mode, *rows
        )
        cross = reformats.CrossRequest(
            doc.volume,
            arch,
            reformats.plan_axis(doc.plan),
            self.at_arc_mm,
            self.cross_controls.slab_mm,
            self.cross_controls.slab_mode,
        )
        if not pano.same_as(self._pano_req):
            self._pano_req = pano
            self.pano_runner.submit(pano.compute)
            self.pano_controls.busy.setText("computing ...")
        if not cross.same_as(self._cross_req):
            self._cross_req = cross
            self.cross_runner.submit(cross.compute)
            self.cross_controls.busy.setText("computing ...")
        self._redraw()

    def set_mode(self, mode: str) -> None:
        """The tool of both images (``navigate``, ``canal``, ``distance``, ``angle``)."""
        for canvas in (self.pano, self.cross):
            canvas.mode = mode
        self.tools.show_mode(mode)

    def go_to(self, point_lps: np.ndarray | None) -> None:
        """The crosshair: marked on both images; the cross-section moves to its place along
        the arch (when it projects on the arch)."""
        for canvas in (self.pano, self.cross):
            canvas.crosshair_lps = point_lps
        arch = self.ctx.doc.arch_lps
        if point_lps is not None and arch is not None:
            try:
                at = reformats.arc_position_mm(arch, point_lps)
            except ValueError:  # an arch the reformat refuses: nothing to move
                at = float("nan")
            if np.isfinite(at):
                self.move_to(at)
                return
        self._redraw()

    def move_to(self, at_arc_mm: float | None) -> None:
        """Put the cross-section at ``at_arc_mm`` along the arch (None: the implant's site)."""
        arch = self.ctx.doc.arch_lps
        if at_arc_mm is not None and arch is not None:
            length = reformats.arch_length_mm(arch)
            at_arc_mm = reformats.scrolled_arc_mm(at_arc_mm, 0.0, length, 1.0)
        self.at_arc_mm = at_arc_mm
        self.refresh()

    def scroll_along(self, steps: float, big: bool = False) -> None:
        """Move the cross-section ``steps`` steps along the arch (+: toward its last point),
        from where it was last asked to be (scrolls faster than it computes add up)."""
        doc = self.ctx.doc
        arch = doc.arch_lps
        if arch is None or doc.volume is None:
            return
        start = self.at_arc_mm
        if start is None:
            try:
                start = reformats.site_arc_mm(arch, doc.plan)
            except ValueError as exc:  # the implant lies beyond the arch's ends
                self.ctx.status(f"error: {exc}")
                return
        step = reformats.BIG_STEP_MM if big else reformats.STEP_MM
        length = reformats.arch_length_mm(arch)
        self.move_to(reformats.scrolled_arc_mm(start, steps, length, step))

    # ------------------------------------------------------------------ results
    def _pano_done(self, image: Reformat) -> None:
        self.pano_image = image
        self.pano_controls.busy.setText("")
        self._redraw()

    def _cross_done(self, image: Reformat) -> None:
        self.cross_image = image
        self.cross_controls.busy.setText("")
        self._redraw()  # the panorama marks where the cross-section is: both

    def _show_readout(self, readout: ImplantReadout | None) -> None:
        """The current (or dragged) implant's figures under the cross-section."""
        self.readout.setText("" if readout is None else readout_text(readout))

    def _failed(self, canvas: ReformatCanvas) -> Any:
        def failed(exc: BaseException, tb: str) -> None:
            if canvas is self.pano:
                self.pano_image, self._pano_req = None, None
                self.pano_controls.busy.setText("")
            else:
                self.cross_image, self._cross_req = None, None
                self.cross_controls.busy.setText("")
            if isinstance(exc, ValueError):  # bad input: the arch, the axis, the slab
                canvas.show_message(f"error: {exc}")
            else:
                canvas.show_message(f"internal error: {exc!r}")
                self.ctx.status(f"internal error in the reformat view: {exc!r}")

        return failed

    def _redraw(self) -> None:
        """Redraw both images with the plan as it is now, each in a UI-thread step of its
        own; a redraw already queued is not queued twice; none while the page is hidden."""
        if not self.isVisible():
            self._dirty = True
            return
        for kind in ("panorama", "cross_section"):
            if kind not in self._queued:
                self._queued.add(kind)
                self.ctx.steps.push(partial(self._queued_draw, kind))

    def _queued_draw(self, kind: str) -> None:
        self._queued.discard(kind)
        if kind == "panorama" and self.pano_image is not None:
            self._draw_pano(self.pano_image)
        elif kind == "cross_section" and self.cross_image is not None:
            self._draw_cross(self.cross_image)

    def _paths(self) -> list[Any]:
        doc = self.ctx.doc
        views = [doc.cached_path(p) for p in doc.plans]
        return [None if v is None else v.result for v in views]

    def _offending(self) -> tuple[bool, ...]:
        """The implants drawn red (:func:`~ctdrill.app.gui.problems.offending_implants`)."""
        doc = self.ctx.doc
        return offending_implants(doc.plans, [doc.cached_path(p) for p in doc.plans])

    def _draw_pano(self, image: Reformat) -> None:
        if image is not self.pano_image:
            return
        doc = self.ctx.doc
        cross = self.cross_image
        draw_reformat(
            self.pano.ax,
            image,
            doc.plans,
            paths=self._paths(),
            cross_section_at_mm=None if cross is None else cross.at_arc_mm,
            offending=self._offending(),
        )
        self.pano.image_drawn(image, doc.plans, doc.current)
        self.drawn.emit("panorama")

    def _draw_cross(self, image: Reformat) -> None:
        if image is not self.cross_image:
            return
        doc = self.ctx.doc
        draw_reformat(
            self.cross.ax, image, doc.plans, paths=self._paths(), offending=self._offending()
        )
        self.cross.image_drawn(image, doc.plans, doc.current)
        arch = doc.arch_lps
        length = 0.0 if arch is None else reformats.arch_length_mm(arch)
        at_implant = self.at_arc_mm is None and doc.plan is not None
        self.position.setText(
            reformats.position_text(image.at_arc_mm, length, at_implant=at_implant)
        )
        self.drawn.emit("cross_section")
