"""The panoramic reformat along the dental arch and the cross-section through the implant.

A page of the main area (beside the 3D and slice views): the panorama on the left, the
cross-section on the right, each with its slab thickness and mean / MIP. The cross-section stands
perpendicular to the arch at the current trajectory's implant site, tilted to contain its axis;
the mouse wheel or the arrow keys over it (Shift or Page Up / Down: bigger steps) scroll it along
the arch, keeping the tilt; a click on the panorama moves it there, and "At implant" brings it
back. Both are computed in worker threads (:mod:`ctdrill.app.gui.reformats`, latest wins) and
drawn with :func:`ctdrill.app.reformat.draw.draw_reformat`, the figure ``ctdrill panorama``
writes: canal and margin zone, implant body, drill to its stop, scale bar. A panorama is
recomputed only when the series, the arch or its slab change; plan edits redraw the overlays.
Nothing is computed while the page is hidden.
"""

from __future__ import annotations

import textwrap
from functools import partial
from typing import Any

from matplotlib.backend_bases import MouseEvent
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QKeyEvent, QResizeEvent, QShowEvent, QWheelEvent
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.gui import reformats
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.workers import Runner
from ctdrill.app.reformat.draw import draw_reformat
from ctdrill.imaging.sampling.reformat import Reformat, SlabMode

#: Keys that scroll the cross-section, in steps (+: toward the arch's last point).
_KEY_STEPS = {
    Qt.Key.Key_Up: 1.0,
    Qt.Key.Key_Right: 1.0,
    Qt.Key.Key_Down: -1.0,
    Qt.Key.Key_Left: -1.0,
}
_PAGE_KEYS = {Qt.Key.Key_PageUp: 1.0, Qt.Key.Key_PageDown: -1.0}


#: Room around the image, display pixels: left (tick labels and the mm label), right, top,
#: and bottom for the tick labels and the x label's first line; each more line adds _LINE_PX.
_MARGINS_PX = (56.0, 14.0, 10.0, 44.0)
_LINE_PX = 17.0


class ReformatCanvas(FigureCanvasQTAgg):
    """One reformat image (or a message saying why there is none)."""

    scrolled = Signal(float, bool)  # steps (+: along the arch), big step
    clicked_mm = Signal(float, float)  # image column, row in mm

    def __init__(self) -> None:
        fig = Figure(figsize=(6.0, 3.0), dpi=80)
        super().__init__(fig)
        self.ax = fig.add_subplot()
        self.message = ""
        self._captions = ""  # the x label and captions as drawn, before wrapping
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.mpl_connect("button_press_event", self._press)

    def image_drawn(self) -> None:
        """An image was just drawn on :attr:`ax`: lay it out and show it."""
        self.message = ""
        self._captions = self.ax.get_xlabel()
        self.fit_captions()
        self.draw_idle()

    def fit_captions(self) -> None:
        """Wrap the lines under the image (x label and captions) to the canvas width and
        leave room for them: a fixed layout (matplotlib's constrained layout costs more than
        the drawing itself)."""
        fig, label = self.figure, self.ax.xaxis.label
        w_px, h_px = max(fig.bbox.width, 100.0), max(fig.bbox.height, 100.0)
        char_px = 0.6 * float(label.get_fontsize()) * fig.dpi / 72.0
        chars = max(20, int((w_px - 20.0) / char_px))
        lines = [
            piece
            for line in self._captions.split("\n")
            for piece in (textwrap.wrap(line, chars) or [""])
        ]
        label.set_text("\n".join(lines))
        left, right, top, bottom = _MARGINS_PX
        bottom += _LINE_PX * (len(lines) - 1)
        self.ax.set_position(
            (left / w_px, bottom / h_px, 1 - (left + right) / w_px, 1 - (top + bottom) / h_px)
        )

    def resizeEvent(self, event: QResizeEvent) -> None:
        super().resizeEvent(event)
        if not self.message and self._captions:
            self.fit_captions()

    def show_message(self, text: str) -> None:
        """Show ``text`` instead of an image."""
        self.message = text
        self.ax.clear()
        self.ax.set_position((0.02, 0.02, 0.96, 0.96))
        self.ax.set_axis_off()
        self.ax.text(
            0.5, 0.5, text, ha="center", va="center", wrap=True, fontsize=11,
            transform=self.ax.transAxes,
        )  # fmt: skip
        self.draw_idle()

    def _press(self, event: MouseEvent) -> None:
        if event.button == 1 and event.inaxes is self.ax and event.xdata is not None:
            self.clicked_mm.emit(float(event.xdata), float(event.ydata or 0.0))

    def wheelEvent(self, event: QWheelEvent) -> None:
        notches = event.angleDelta().y() / 120.0
        if notches:
            big = bool(event.modifiers() & Qt.KeyboardModifier.ShiftModifier)
            self.scrolled.emit(notches, big)
        event.accept()

    def keyPressEvent(self, event: QKeyEvent) -> None:
        key = Qt.Key(event.key())
        if key in _KEY_STEPS:
            big = bool(event.modifiers() & Qt.KeyboardModifier.ShiftModifier)
            self.scrolled.emit(_KEY_STEPS[key], big)
        elif key in _PAGE_KEYS:
            self.scrolled.emit(_PAGE_KEYS[key], True)
        else:
            super().keyPressEvent(event)


class SlabControls(QWidget):
    """A title, the slab thickness and mean / MIP, and room for more widgets."""

    changed = Signal()

    def __init__(self, title: str, slab_mm: float) -> None:
        super().__init__()
        self.row = QHBoxLayout(self)
        self.row.setContentsMargins(4, 0, 4, 0)
        label = QLabel(f"<b>{title}</b>")
        self.slab = QDoubleSpinBox()
        self.slab.setRange(0.0, 30.0)
        self.slab.setSingleStep(0.5)
        self.slab.setDecimals(1)
        self.slab.setSuffix(" mm")
        self.slab.setValue(slab_mm)
        self.slab.setKeyboardTracking(False)
        self.slab.setToolTip("slab thickness across the image (0: one plane)")
        self.mode = QComboBox()
        self.mode.addItems(["mean", "MIP"])
        self.mode.setToolTip("mean of the slab, or its maximum (MIP: bone and implants stand out)")
        #: "computing ..." while its image is computed in the background
        self.busy = QLabel("")
        self.busy.setStyleSheet("color:#6a1b9a")
        for w in (label, QLabel("slab"), self.slab, self.mode, self.busy):
            self.row.addWidget(w)
        self.slab.valueChanged.connect(lambda _v: self.changed.emit())
        self.mode.currentIndexChanged.connect(lambda _i: self.changed.emit())

    @property
    def slab_mm(self) -> float:
        """The slab thickness, mm."""
        return float(self.slab.value())

    @property
    def slab_mode(self) -> SlabMode:
        """``mean`` or ``mip``."""
        return "mip" if self.mode.currentIndex() == 1 else "mean"


class PanoramaView(QWidget):
    """Panorama beside cross-section, each computed off the UI thread."""

    #: Emitted after an image is drawn (``panorama`` or ``cross_section``), for tests.
    drawn = Signal(str)

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.pano_controls = SlabControls("Panorama", reformats.PANORAMA_SLAB_MM)
        self.cross_controls = SlabControls("Cross-section", reformats.CROSS_SLAB_MM)
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
        self.pano = ReformatCanvas()
        self.cross = ReformatCanvas()
        split = QSplitter(Qt.Orientation.Horizontal)
        for widgets in (
            (self.pano_controls, self.pano),
            (self.cross_controls, self.position, self.cross),
        ):
            pane = QWidget()
            lay = QVBoxLayout(pane)
            lay.setContentsMargins(0, 0, 0, 0)
            for widget in widgets:
                lay.addWidget(widget, 1 if isinstance(widget, ReformatCanvas) else 0)
            split.addWidget(pane)
        split.setSizes([600, 400])
        QVBoxLayout(self).addWidget(split)
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
        self.pano.clicked_mm.connect(lambda x_mm, _y: self.move_to(x_mm))
        self.cross.scrolled.connect(self.scroll_along)
        doc = ctx.doc
        doc.volume_changed.connect(lambda _v: self.refresh())
        doc.plans_changed.connect(lambda _p: self.refresh())
        doc.path_changed.connect(lambda _v: self._redraw())
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
        pano = reformats.PanoramaRequest(
            doc.volume, arch, self.pano_controls.slab_mm, self.pano_controls.slab_mode
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
        )
        self.pano.image_drawn()
        self.drawn.emit("panorama")

    def _draw_cross(self, image: Reformat) -> None:
        if image is not self.cross_image:
            return
        doc = self.ctx.doc
        draw_reformat(self.cross.ax, image, doc.plans, paths=self._paths())
        self.cross.image_drawn()
        arch = doc.arch_lps
        length = 0.0 if arch is None else reformats.arch_length_mm(arch)
        at_implant = self.at_arc_mm is None and doc.plan is not None
        self.position.setText(
            reformats.position_text(image.at_arc_mm, length, at_implant=at_implant)
        )
        self.drawn.emit("cross_section")
