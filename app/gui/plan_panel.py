"""The planning panel: numeric entry/target, drill and feed, calibration, landmark margins.

The panel shows a plan and reports edits as a new plan (``plan_edited``); every edit goes
through :mod:`ctdrill.app.gui.planning` (pure functions), so the panel holds no planning logic.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import partial

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.gui import planning
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.model import available_calibrations


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

    plan_edited = Signal(object)  # the new Plan
    edit_rejected = Signal(str)  # a message naming the field
    add_canal_toggled = Signal(bool)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.plan: Plan | None = None
        self._updating = False
        self._rows_key: tuple[tuple[str, str], ...] | None = None
        outer = QVBoxLayout(self)

        traj = QGroupBox("Trajectory (LPS, mm)")
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

        drill = QGroupBox("Drill and feed")
        form = QFormLayout(drill)
        self.diameter = _spin(0.5, 10.0, 0.1, 2, " mm")
        self.tip_length = _spin(0.0, 5.0, 0.1, 2, " mm")
        self.feed = _spin(0.01, 10.0, 0.05, 2, " mm/s")
        self.margin = _spin(0.0, 10.0, 0.1, 2, " mm")
        self.calibration = QComboBox()
        self.calibration.setEditable(True)
        self.calibration.addItems(list(available_calibrations()))
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
        self.table = QTableWidget(0, 4)
        self.table.setHorizontalHeaderLabels(["name", "kind", "margin", "clearance"])
        self.table.verticalHeader().setVisible(False)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(0, QHeaderView.ResizeMode.Stretch)
        for col in (1, 2, 3):
            header.setSectionResizeMode(col, QHeaderView.ResizeMode.ResizeToContents)
        self.table.setWordWrap(True)
        lay.addWidget(self.table)
        buttons = QHBoxLayout()
        self.add_canal = QPushButton("Add canal points")
        self.add_canal.setCheckable(True)
        self.add_canal.setToolTip("Click on a slice view to append points to the canal")
        self.add_canal.toggled.connect(self.add_canal_toggled)
        self.remove = QPushButton("Remove")
        self.remove.clicked.connect(self._remove_landmark)
        buttons.addWidget(self.add_canal)
        buttons.addWidget(self.remove)
        lay.addLayout(buttons)
        outer.addWidget(lms)
        outer.addStretch(1)
        self.setEnabled(False)

    # ------------------------------------------------------------------ show
    def set_plan(self, plan: Plan, clearance_mm: np.ndarray | None = None) -> None:
        """Show ``plan`` (no signals are emitted); ``clearance_mm`` (L,) per landmark."""
        self._updating = True
        try:
            self.plan = plan
            self.setEnabled(True)
            for name, pt in (("entry", plan.entry_lps), ("target", plan.target_lps)):
                for box, value in zip(self.point_boxes[name], pt, strict=True):
                    box.setValue(float(value))
            self.depth_label.setText(f"planned depth: {plan.planned_depth_mm:.2f} mm")
            self.diameter.setValue(plan.drill.diameter_mm)
            self.tip_length.setValue(plan.drill.tip_length_mm)
            self.feed.setValue(plan.feed_mm_s)
            self.margin.setValue(plan.margin_mm)
            self.calibration.setCurrentText(plan.calibration)
            if clearance_mm is not None and len(clearance_mm) != len(plan.landmarks):
                clearance_mm = None  # computed for another landmark list
            key = tuple((lm.name, lm.kind) for lm in plan.landmarks)
            if key != self._rows_key:  # rebuild the rows only when the landmarks change
                self._rows_key = key
                self.table.setRowCount(len(plan.landmarks))
                for row, lm in enumerate(plan.landmarks):
                    for col, text in enumerate((lm.name, lm.kind)):
                        item = QTableWidgetItem(text)
                        item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                        self.table.setItem(row, col, item)
                    spin = _spin(0.0, 10.0, 0.1, 2, " mm")
                    spin.valueChanged.connect(partial(self._margin_edited, row))
                    self.table.setCellWidget(row, 2, spin)
            for row, lm in enumerate(plan.landmarks):
                cell = self.table.cellWidget(row, 2)
                if isinstance(cell, QDoubleSpinBox):
                    cell.setValue(plan.landmark_margin_mm(lm))
                clear = "-" if clearance_mm is None else f"{float(clearance_mm[row]):.2f} mm"
                self.table.setItem(row, 3, QTableWidgetItem(clear))
        finally:
            self._updating = False

    # ------------------------------------------------------------------ edits
    def _emit(self, fn: Callable[[], Plan]) -> None:
        if self._updating or self.plan is None:
            return
        try:
            new = fn()
        except ValueError as exc:
            self.edit_rejected.emit(str(exc))
            self.set_plan(self.plan)
            return
        self.plan = new
        self.depth_label.setText(f"planned depth: {new.planned_depth_mm:.2f} mm")
        self.plan_edited.emit(new)

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
            drill = DrillSpec(
                diameter_mm=self.diameter.value(),
                tip_length_mm=self.tip_length.value(),
                blades=plan.drill.blades,
                rpm=plan.drill.rpm,
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

    def _remove_landmark(self) -> None:
        plan = self.plan
        row = self.table.currentRow()
        if plan is None or row < 0 or row >= len(plan.landmarks):
            return
        self._emit(lambda: planning.remove_landmark(plan, row))
        self.set_plan(self.plan if self.plan is not None else plan)
