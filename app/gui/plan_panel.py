"""The planning panel: the trajectories, the current one's numeric entry/target, implant,
drill sequence and feed, calibration, the landmarks (name, margin, the planned clearance of the
implant and of the osteotomy, a canal's radius).

The panel shows the document's plan and the clearances of its path, and hands every edit to
the document as a new plan; every edit goes through :mod:`ctdrill.app.gui.planning` (pure
functions), so the panel holds no planning logic. While a rehearsal runs the panel is locked
(the device holds the plan it was armed with) and says so.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import partial

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.gui import canal_edit, planning
from ctdrill.app.gui.canal_edit import MAX_RADIUS_MM
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.implant_picker import ImplantPicker
from ctdrill.app.gui.problems import planned_cells
from ctdrill.app.gui.reformat_canvas import CanalChoice
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.trajectory_list import TrajectoryList
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import Plan
from ctdrill.model import available_calibrations, load_calibration

#: The landmark table's columns.
COLUMNS = ("name", "kind", "margin", "implant", "osteotomy", "radius")
#: What the two clearance columns hold (their header tooltips).
COLUMN_TIPS = {
    "implant": "planned clearance of the implant body at its placement (apex at the target)",
    "osteotomy": "planned clearance of the osteotomy: every drill drilled to the implant's "
    "apex plus its tip, the least over the drills",
}
#: Width of the spin boxes in the landmarks table (margin, radius), px.
CELL_SPIN_PX = 78


#: Item data marking a clearance cell that waits for the path result ("unknown").
_PENDING_ROLE = Qt.ItemDataRole.UserRole + 1


def _show_value(box: QDoubleSpinBox, value: float) -> None:
    """Show ``value`` in ``box`` unless it shows it already (a spin box repaints on every
    ``setValue``, and the plan is shown again on every edit and path result)."""
    if box.value() != box.valueFromText(box.textFromValue(value)):
        box.setValue(value)


def _show_text(edit: QLineEdit, text: str) -> None:
    """Show ``text`` in ``edit`` unless it shows it already (a line edit repaints on every
    ``setText``)."""
    if edit.text() != text:
        edit.setText(text)


def _spin(lo: float, hi: float, step: float, decimals: int, suffix: str) -> QDoubleSpinBox:
    box = QDoubleSpinBox()
    box.setRange(lo, hi)
    box.setSingleStep(step)
    box.setDecimals(decimals)
    box.setSuffix(suffix)
    box.setKeyboardTracking(False)  # one edit per committed value, not per keystroke
    return box


class PlanPanel(QWidget):
    """Numeric plan editor."""

    add_canal_toggled = Signal(bool)

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.plan: Plan | None = None
        self._updating = False
        self._rows_key: tuple[tuple[str, str], ...] | None = None
        outer = QVBoxLayout(self)
        self.lock_label = QLabel("")
        self.lock_label.setWordWrap(True)
        self.lock_label.setStyleSheet("color:#6a1b9a; font-weight:bold")
        outer.addWidget(self.lock_label)
        self.body = QWidget()
        outer.addWidget(self.body)
        outer = QVBoxLayout(self.body)
        outer.setContentsMargins(0, 0, 0, 0)
        self.trajectories = TrajectoryList(ctx)
        outer.addWidget(self.trajectories)

        traj = QGroupBox("Current trajectory (LPS, mm)")
        grid = QGridLayout(traj)
        self.point_boxes: dict[str, list[QDoubleSpinBox]] = {}
        for col, axis in enumerate(("x (L)", "y (P)", "z (S)")):
            grid.addWidget(QLabel(axis), 0, col + 1)
        for row, name in enumerate(("entry", "target")):
            grid.addWidget(QLabel(name), row + 1, 0)
            boxes = [_spin(-2000.0, 2000.0, 0.5, 2, "") for _ in range(3)]
            for col, box in enumerate(boxes):
                grid.addWidget(box, row + 1, col + 1)
                box.valueChanged.connect(lambda _v, n=name: self._point_edited(n))
            self.point_boxes[name] = boxes
        self.depth_label = QLabel("planned depth: -")
        grid.addWidget(self.depth_label, 3, 0, 1, 4)
        outer.addWidget(traj)

        drill = QGroupBox("Implant, drill and feed")
        form = QFormLayout(drill)
        self.implant = ImplantPicker(ctx)
        form.addRow("implant", self.implant)
        #: the implant's site, an FDI tooth number (validated; empty: not given)
        self.site = QLineEdit()
        self.site.setObjectName("field:site")
        self.site.setPlaceholderText("FDI, e.g. 36")
        self.site.setToolTip("The implant site as an FDI tooth number 11-48; Enter applies")
        self.site.editingFinished.connect(self._site_edited)
        form.addRow("site (FDI)", self.site)
        self.diameter = _spin(0.5, 10.0, 0.1, 2, " mm")
        self.tip_length = _spin(0.0, 5.0, 0.1, 2, " mm")
        self.feed = _spin(0.01, 10.0, 0.05, 2, " mm/s")
        self.margin = _spin(0.0, 10.0, 0.1, 2, " mm")
        self.calibration = QComboBox()
        self.calibration.setEditable(True)
        self.calibration.addItems(list(available_calibrations()))
        for i, name in enumerate(available_calibrations()):  # which set, and how obtained
            self.calibration.setItemData(i, calibration_tooltip(name), Qt.ItemDataRole.ToolTipRole)
        #: the drill sequence (diameters in drilling order); the fields below edit the final drill
        self.sequence = QLineEdit()
        self.sequence.setToolTip(
            "The drills in drilling order, diameters in mm (e.g. 2 -> 2.8 -> 3.5); Enter "
            "applies. The last is the final drill, edited by the fields below."
        )
        self.sequence.editingFinished.connect(self._sequence_edited)
        form.addRow("drills (mm)", self.sequence)
        form.addRow("diameter", self.diameter)
        form.addRow("tip length", self.tip_length)
        form.addRow("feed", self.feed)
        form.addRow("safety margin", self.margin)
        form.addRow("calibration", self.calibration)
        for box in (self.diameter, self.tip_length, self.feed, self.margin):
            box.valueChanged.connect(self._settings_edited)
        self.calibration.activated.connect(self._settings_edited)
        line_edit = self.calibration.lineEdit()
        if line_edit is not None:
            line_edit.editingFinished.connect(self._settings_edited)
        outer.addWidget(drill)

        lms = QGroupBox("Landmarks")
        lay = QVBoxLayout(lms)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        for col, name in enumerate(COLUMNS):
            header_item = self.table.horizontalHeaderItem(col)
            if name in COLUMN_TIPS and header_item is not None:
                header_item.setToolTip(COLUMN_TIPS[name])
        self.table.setToolTip("double-click a name to rename the landmark")
        self.table.verticalHeader().setVisible(False)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(0, QHeaderView.ResizeMode.Stretch)
        header.setMinimumSectionSize(40)
        for col in range(1, len(COLUMNS)):
            header.setSectionResizeMode(col, QHeaderView.ResizeMode.ResizeToContents)
        self.table.setWordWrap(True)
        self.table.itemChanged.connect(self._landmark_renamed)
        lay.addWidget(self.table)
        buttons = QHBoxLayout()
        self.add_canal = QPushButton("Trace canal")
        self.add_canal.setCheckable(True)
        self.add_canal.setToolTip(
            "Click along a canal on a slice view to trace it (the canal of the side clicked, "
            "or the one chosen in the slice toolbar); the panorama page traces too"
        )
        self.add_canal.toggled.connect(self.add_canal_toggled)
        self.remove = QPushButton("Remove")
        self.remove.clicked.connect(self._remove_landmark)
        buttons.addWidget(self.add_canal)
        buttons.addWidget(self.remove)
        lay.addLayout(buttons)
        #: which canal tracing goes to and a new canal's radius (shared with the panorama page)
        self.canal_choice = CanalChoice(ctx.doc)
        lay.addWidget(self.canal_choice)
        outer.addWidget(lms)
        outer.addStretch(1)
        self.body.setEnabled(False)
        ctx.doc.plan_changed.connect(self._plan_changed)
        ctx.doc.path_changed.connect(self._path_changed)
        ctx.doc.rehearsal_changed.connect(self._rehearsal_changed)

    # ------------------------------------------------------------------ document
    def _plan_changed(self, plan: Plan | None) -> None:
        if plan is None:
            self.plan = None
            self.body.setEnabled(False)
        else:
            self.set_plan(plan)

    def _path_changed(self, view: PathView | None) -> None:
        plan = self.ctx.doc.plan
        if plan is None:
            return
        own = view is not None and view.plan is plan
        self.set_plan(plan)
        if not own or view is None or view.planned is None:
            return
        if len(view.planned.margins_mm) != len(plan.landmarks):
            return  # computed for another landmark list
        cells = planned_cells(plan, view.planned, view.min_clearance_mm)
        for row, pair in enumerate(cells):
            for col, (text, tip, broken) in zip((3, 4), pair, strict=True):
                item = QTableWidgetItem(text)
                item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                item.setToolTip(tip)
                if broken:
                    item.setForeground(QColor("#c62828"))
                self.table.setItem(row, col, item)

    def _rehearsal_changed(self, running: bool) -> None:
        self.body.setEnabled(not running and self.plan is not None)
        self.lock_label.setText(
            "The plan is locked while the rehearsal runs (the device holds the plan it was "
            "armed with): stop the rehearsal to edit it."
            if running
            else ""
        )

    # ------------------------------------------------------------------ show
    def set_plan(self, plan: Plan) -> None:
        """Show ``plan`` (no signals are emitted); its planned clearances unknown until its
        path result arrives."""
        self._updating = True
        try:
            self.plan = plan
            self.body.setEnabled(not self.ctx.doc.rehearsing)
            for name, pt in (("entry", plan.entry_lps), ("target", plan.target_lps)):
                for box, value in zip(self.point_boxes[name], pt, strict=True):
                    _show_value(box, float(value))
            self.depth_label.setText(f"planned depth: {plan.planned_depth_mm:.2f} mm")
            _show_text(self.sequence, planning.drills_text(plan))
            self.implant.show_plan(plan)
            _show_text(self.site, "" if plan.site is None else str(plan.site))
            _show_value(self.diameter, plan.drill.diameter_mm)
            _show_value(self.tip_length, plan.drill.tip_length_mm)
            _show_value(self.feed, plan.feed_mm_s)
            _show_value(self.margin, plan.margin_mm)
            self.calibration.setCurrentText(plan.calibration)
            key = tuple((lm.name, lm.kind) for lm in plan.landmarks)
            if key != self._rows_key:  # rebuild the rows only when the landmarks change
                self._rows_key = key
                self.table.setRowCount(len(plan.landmarks))
                for row, lm in enumerate(plan.landmarks):
                    for col, text in enumerate((lm.name, lm.kind)):
                        item = QTableWidgetItem(text)
                        if col == 1:
                            item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                        self.table.setItem(row, col, item)
                    spin = _spin(0.0, 10.0, 0.1, 2, " mm")
                    spin.setMaximumWidth(CELL_SPIN_PX)
                    spin.valueChanged.connect(partial(self._margin_edited, row))
                    self.table.setCellWidget(row, 2, spin)
                    if isinstance(lm, CanalLandmark):
                        radius = _spin(0.1, MAX_RADIUS_MM, 0.1, 2, " mm")
                        radius.setMaximumWidth(CELL_SPIN_PX)
                        radius.valueChanged.connect(partial(self._radius_edited, row))
                        self.table.setCellWidget(row, 5, radius)
                    else:
                        self.table.removeCellWidget(row, 5)
            for row, lm in enumerate(plan.landmarks):
                cell = self.table.cellWidget(row, 2)
                if isinstance(cell, QDoubleSpinBox):
                    _show_value(cell, plan.landmark_margin_mm(lm))
                cell = self.table.cellWidget(row, 5)
                if isinstance(cell, QDoubleSpinBox):
                    _show_value(cell, float(lm.radius_mm))
                for col in (3, 4):
                    shown = self.table.item(row, col)
                    if shown is not None and shown.data(_PENDING_ROLE) is True:
                        continue  # "unknown" already
                    item = QTableWidgetItem("unknown")
                    item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                    item.setData(_PENDING_ROLE, True)
                    self.table.setItem(row, col, item)
        finally:
            self._updating = False

    # ------------------------------------------------------------------ edits
    def _emit(self, fn: Callable[[], Plan]) -> None:
        if self._updating or self.plan is None:
            return
        try:
            new = fn()
        except ValueError as exc:
            self.ctx.doc.edit_refused.emit(f"error: {exc}")
            self.set_plan(self.plan)
            return
        if not self.ctx.doc.set_plan(new) and self.ctx.doc.plan is not None:
            self.set_plan(self.ctx.doc.plan)  # refused: show the plan that holds

    def _point_edited(self, name: str) -> None:
        plan = self.plan
        if plan is None:
            return
        pt = np.array([b.value() for b in self.point_boxes[name]])
        self._emit(lambda: planning.move_handle(plan, name, pt))

    def _settings_edited(self, *_args: object) -> None:
        plan = self.plan
        if plan is None:
            return

        def edit() -> Plan:
            drill = planning.final_drill_edited(
                plan, diameter_mm=self.diameter.value(), tip_length_mm=self.tip_length.value()
            )
            calibration = self.calibration.currentText().strip() or plan.calibration
            return replace(
                plan,
                drill=drill,
                feed_mm_s=self.feed.value(),
                margin_mm=self.margin.value(),
                calibration=calibration,
            )

        self._emit(edit)

    def _margin_edited(self, row: int, value: float) -> None:
        plan = self.plan
        if plan is None:
            return
        self._emit(lambda: planning.set_landmark_margin(plan, row, value))

    def _radius_edited(self, row: int, value: float) -> None:
        plan = self.plan
        if plan is None:
            return
        self._emit(lambda: canal_edit.set_radius(plan, row, value))

    def _landmark_renamed(self, item: QTableWidgetItem) -> None:
        plan = self.plan
        if self._updating or plan is None or item.column() != 0:
            return
        row, text = item.row(), item.text()
        if row < len(plan.landmarks) and text != plan.landmarks[row].name:
            self._emit(lambda: canal_edit.rename_landmark(plan, row, text))

    def _site_edited(self) -> None:
        plan = self.plan
        if self._updating or plan is None:
            return
        text = self.site.text().strip()
        if text == ("" if plan.site is None else str(plan.site)):
            return
        self._emit(lambda: planning.with_site(plan, text))

    def _sequence_edited(self) -> None:
        plan = self.plan
        if plan is None or self.sequence.text().strip() == planning.drills_text(plan):
            return
        text = self.sequence.text()
        self._emit(lambda: planning.with_drill_sequence(plan, text))

    def _remove_landmark(self) -> None:
        plan = self.plan
        row = self.table.currentRow()
        if plan is None or row < 0 or row >= len(plan.landmarks):
            return
        self._emit(lambda: planning.remove_landmark(plan, row))


def calibration_tooltip(name: str) -> str:
    """What the set is and how it was obtained (its provenance or source), for a tooltip."""
    from ctdrill.app.summary_lines import calibration_line
    from ctdrill.engine.summary import CalibrationInfo

    cal = load_calibration(name)
    band = "with a 68 % force band" if cal.covariance is not None else "no uncertainty band"
    return f"{calibration_line(CalibrationInfo.of(cal))} ({band})"
