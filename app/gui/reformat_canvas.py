"""The panoramic's and the cross-section's canvases, their slab controls and their tool row.

A :class:`ReformatCanvas` shows one :class:`~ctdrill.imaging.sampling.reformat.Reformat` drawn
by :func:`ctdrill.app.reformat.draw.draw_reformat` in image millimetres, mapped to the patient by
:meth:`Reformat.lps_at` and :meth:`Reformat.project` (:class:`ReformatMap`): a click on the
panoramic lands at the exact LPS of the point clicked on its curved curtain. It has the shared
tools of :class:`~ctdrill.app.gui.map_canvas.MapCanvas` (canal tracing, distance, angle, the
link click) and, on the cross-section, the current implant's grips.
"""

from __future__ import annotations

import textwrap

import numpy as np
from matplotlib.figure import Figure
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QKeyEvent, QResizeEvent, QWheelEvent
from PySide6.QtWidgets import (
    QButtonGroup,
    QComboBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QToolButton,
    QWidget,
)

from ctdrill.app.gui.document import Document
from ctdrill.app.gui.implant_drag import grips_lps
from ctdrill.app.gui.map_canvas import MapCanvas
from ctdrill.app.gui.slice_scene import canal_points
from ctdrill.app.reformat.overlay import body_overlay, drill_profile_mm
from ctdrill.app.reformat.placement import implant_body
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import Plan
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
#: Points within this distance of a reformat's surface are on it (picking, lps_to_pixel),
#: beyond half its slab, mm.
ON_IMAGE_MM = 1.0
#: The tool row's tools: mode, button text, tooltip.
TOOLS = (
    ("navigate", "Navigate", "Click: link the views there (the cross-section moves to it); "
     "on the cross-section drag the implant (Shift: along its axis), its platform tilts it"),
    ("canal", "Trace canal", "Click along the canal to trace it; drag a point to move it; "
     "right-click or Delete removes it"),
    ("distance", "Distance", "Two clicks: the distance in the patient, mm"),
    ("angle", "Angle", "Three clicks: arm, vertex, arm; the angle in degrees"),
)  # fmt: skip
#: The canal choice meaning "the canal of the side clicked".
AUTO_CANAL = "left / right by side"


class ReformatMap:
    """A reformat as a :class:`~ctdrill.app.gui.map_ghost.PlaneMap`."""

    def __init__(self, reformat: Reformat) -> None:
        self.reformat = reformat

    def to_lps(self, uv_mm: np.ndarray) -> np.ndarray:
        return self.reformat.lps_at(uv_mm)

    def to_uv(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pts = np.asarray(points_lps, dtype=np.float64)
        uv, off = self.reformat.project(pts.reshape(-1, 3))
        return uv.reshape(*pts.shape[:-1], 2), off.reshape(pts.shape[:-1])


class ReformatCanvas(MapCanvas):
    """One reformat image (or a message saying why there is none)."""

    scrolled = Signal(float, bool)  # steps (+: along the arch), big step

    def __init__(self, object_name: str = "") -> None:
        fig = Figure(figsize=(6.0, 3.0), dpi=80)
        super().__init__(fig)
        if object_name:
            self.setObjectName(object_name)
        self.ax = fig.add_subplot()
        self.message = ""
        self.reformat: Reformat | None = None
        self._captions = ""  # the x label and captions as drawn, before wrapping
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)

    def image_drawn(self, reformat: Reformat, plans: tuple[Plan, ...], current: int) -> None:
        """``reformat`` was just drawn on :attr:`ax` with ``plans``: map it, take the grips
        (the cross-section's: the current trajectory's), lay it out and show it."""
        self.message = ""
        self.reformat = reformat
        self.plane_map = ReformatMap(reformat)
        self.on_plane_mm = 0.5 * reformat.slab_mm + ON_IMAGE_MM
        plan = plans[current] if plans else None
        self.canals = [] if plan is None else list(canal_points(plan))
        on_cross = reformat.kind == "cross_section" and plan is not None
        self.grip_plan = plan if on_cross else None
        self.grips = grips_lps(plan) if on_cross and plan is not None else {}
        self.tools.draw()
        self.draw_crosshair()
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
        self.reformat, self.plane_map = None, None
        self.grips, self.grip_plan, self.canals = {}, None, []
        self.ax.clear()
        self.ax.set_position((0.02, 0.02, 0.96, 0.96))
        self.ax.set_axis_off()
        self.ax.text(
            0.5, 0.5, text, ha="center", va="center", wrap=True, fontsize=11,
            transform=self.ax.transAxes,
        )  # fmt: skip
        self.draw_idle()

    def ghost_lines(self, plan: Plan) -> list[np.ndarray]:
        """The dragged trajectory's implant and drill outlines and axis on this image."""
        if self.reformat is None:
            return []
        out = []
        body = implant_body(plan)
        if body is not None:
            base, axis, s, r, _name = body
            out.append(body_overlay(self.reformat, base, axis, s, r, "").outline_uv)
        s, r = drill_profile_mm(
            plan.planned_depth_mm, plan.drill.diameter_mm, plan.drill.tip_length_mm
        )
        drill = body_overlay(self.reformat, plan.entry_lps, plan.direction, s, r, "")
        out += [drill.outline_uv, drill.axis_uv]
        return [line for line in out if np.all(np.isfinite(line))]

    def arch_points(self) -> np.ndarray | None:
        """No arch editing on a reformat."""
        return None

    def emit_arch_edit(self, op: str, index: int, point_lps: np.ndarray | None) -> None:
        """No arch editing on a reformat."""

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
        elif key in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace, Qt.Key.Key_Escape):
            self.delete_under_cursor()
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


class CanalChoice(QWidget):
    """Which canal traced points go to, and a new canal's radius: the document's trace
    settings (``Document.live``), shared by every tool row that shows one."""

    def __init__(self, doc: Document) -> None:
        super().__init__()
        self.doc = doc
        row = QHBoxLayout(self)
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(QLabel("canal"))
        self.canal = QComboBox()
        self.canal.setEditable(True)
        self.canal.setToolTip(
            "Which canal traced points go to: by the side clicked (the patient's left or "
            "right of the arch's middle), an existing canal, or a new name"
        )
        self.canal.activated.connect(lambda _i: self._canal_chosen())
        line = self.canal.lineEdit()
        if line is not None:
            line.editingFinished.connect(self._canal_chosen)
        row.addWidget(self.canal)
        self.radius = QDoubleSpinBox()
        self.radius.setRange(0.1, 10.0)
        self.radius.setSingleStep(0.1)
        self.radius.setDecimals(2)
        self.radius.setSuffix(" mm")
        self.radius.setKeyboardTracking(False)
        self.radius.setToolTip(
            "radius of a canal traced from now on (the Plan tab edits a canal's)"
        )
        self.radius.setValue(doc.live.trace_radius_mm)
        self.radius.valueChanged.connect(lambda v: doc.live.set_trace(radius_mm=v))
        row.addWidget(QLabel("radius"))
        row.addWidget(self.radius)
        doc.plans_changed.connect(lambda _p: self.refresh())
        doc.live.trace_changed.connect(self.refresh)
        self.refresh()

    def refresh(self) -> None:
        """The canal choices: by side, then the plan's canals; the settings shown."""
        plan = self.doc.plan
        names = [] if plan is None else [n for _i, n in _canal_names(plan)]
        items = [AUTO_CANAL, *names]
        wanted = self.doc.live.trace_canal or AUTO_CANAL
        self.canal.blockSignals(True)
        try:  # only what changed: each plan edit (a canal click) refreshes this row
            if [self.canal.itemText(i) for i in range(self.canal.count())] != items:
                self.canal.clear()
                self.canal.addItems(items)
            if self.canal.currentText() != wanted:
                self.canal.setCurrentText(wanted)
        finally:
            self.canal.blockSignals(False)
        if self.radius.value() != self.doc.live.trace_radius_mm:
            self.radius.blockSignals(True)
            self.radius.setValue(self.doc.live.trace_radius_mm)
            self.radius.blockSignals(False)

    def _canal_chosen(self) -> None:
        text = self.canal.currentText().strip()
        self.doc.live.set_trace(canal="" if text in ("", AUTO_CANAL) else text)


class ReformatTools(QWidget):
    """The page's tool row: the tool of both images and the canal tracing's settings."""

    mode_changed = Signal(str)

    def __init__(self, doc: Document) -> None:
        super().__init__()
        row = QHBoxLayout(self)
        row.setContentsMargins(4, 0, 4, 0)
        self.group = QButtonGroup(self)
        self.buttons: dict[str, QToolButton] = {}
        for mode, text, tip in TOOLS:
            button = QToolButton()
            button.setText(text)
            button.setToolTip(tip)
            button.setCheckable(True)
            button.clicked.connect(lambda _c=False, m=mode: self.mode_changed.emit(m))
            self.group.addButton(button)
            self.buttons[mode] = button
            row.addWidget(button)
        self.buttons["navigate"].setChecked(True)
        row.addSpacing(8)
        self.choice = CanalChoice(doc)
        row.addWidget(self.choice)
        row.addStretch(1)

    def show_mode(self, mode: str) -> None:
        """Check the button of ``mode``."""
        if mode in self.buttons:
            self.buttons[mode].setChecked(True)


def _canal_names(plan: Plan) -> list[tuple[int, str]]:
    return [(i, lm.name) for i, lm in enumerate(plan.landmarks) if isinstance(lm, CanalLandmark)]
