"""The plan's trajectories (one per implant): pick the current one, add, remove, rename.

A part of the Plan tab (:class:`~ctdrill.app.gui.plan_panel.PlanPanel`). Every change goes to
the document (:meth:`~ctdrill.app.gui.document.Document.select`, ``add_plan``, ``remove_plan``,
``set_plan``) through the pure edits of :mod:`ctdrill.app.gui.planning`; the list only shows
the document's :attr:`~ctdrill.app.gui.document.Document.plans`.
"""

from __future__ import annotations

from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import (
    QAbstractItemView,
    QGroupBox,
    QHBoxLayout,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QVBoxLayout,
)

from ctdrill.app.gui import planning
from ctdrill.app.gui.document import ViewContext
from ctdrill.imaging.plan.types import Plan

#: Rows the list shows before it scrolls.
VISIBLE_ROWS = 4


def trajectory_label(index: int, plan: Plan) -> str:
    """A list row: ``2. 36  (implant 4.1 x 10 mm, drill 3.5 mm)``."""
    implant = plan.implant
    body = "no implant" if implant is None else f"implant {implant.size_text}"
    return f"{index + 1}. {plan.name}  ({body}, drill {plan.drill.diameter_mm:g} mm)"


class TrajectoryList(QGroupBox):
    """The list of trajectories with Add / Remove / Rename."""

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__("Trajectories (one per implant)")
        self.ctx = ctx
        self._updating = False
        lay = QVBoxLayout(self)
        self.list = QListWidget()
        self.list.setToolTip(
            "The current trajectory is edited, drawn highlighted and its path computed; "
            "double-click a name to rename it"
        )
        row_h = self.list.fontMetrics().height() + 6
        self.list.setMaximumHeight(VISIBLE_ROWS * row_h + 8)
        self.list.currentRowChanged.connect(self._selected)
        self.list.itemChanged.connect(self._renamed)
        # Renaming edits the bare name (not the row's label); Escape shows the label again.
        self.list.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.list.itemDoubleClicked.connect(lambda _item: self._edit_name())
        # The list is rebuilt only after the editor is gone (a rebuild inside the editor's
        # own signals deletes the item it is committing: Qt crashes).
        self.list.itemDelegate().closeEditor.connect(
            lambda *_args: QTimer.singleShot(0, self.refresh)
        )
        lay.addWidget(self.list)
        buttons = QHBoxLayout()
        self.add = QPushButton("Add")
        self.add.setToolTip(
            "Add a trajectory next to the current one (a copy moved along the arch): "
            "drag it into place"
        )
        self.add.clicked.connect(self.add_trajectory)
        self.remove = QPushButton("Remove")
        self.remove.clicked.connect(self.remove_trajectory)
        self.rename = QPushButton("Rename")
        self.rename.clicked.connect(self._edit_name)
        for button in (self.add, self.remove, self.rename):
            buttons.addWidget(button)
        lay.addLayout(buttons)
        ctx.doc.plans_changed.connect(lambda _plans: self.refresh())
        ctx.doc.rehearsal_changed.connect(lambda _running: self.refresh())
        self.refresh()

    def refresh(self) -> None:
        """Show the document's trajectories, the current one selected."""
        doc = self.ctx.doc
        self._updating = True
        try:
            self.list.clear()
            for i, plan in enumerate(doc.plans):
                item = QListWidgetItem(trajectory_label(i, plan))
                item.setData(Qt.ItemDataRole.UserRole, plan.name)
                item.setFlags(item.flags() | Qt.ItemFlag.ItemIsEditable)
                self.list.addItem(item)
            if doc.plans:
                self.list.setCurrentRow(doc.current)
        finally:
            self._updating = False
        editable = bool(doc.plans) and not doc.rehearsing
        for widget in (self.add, self.remove, self.rename, self.list):
            widget.setEnabled(editable)

    # ------------------------------------------------------------------ edits
    def _selected(self, row: int) -> None:
        if self._updating or row < 0:
            return
        if not self.ctx.doc.select(row):
            self.refresh()  # refused: show the current one again

    def add_trajectory(self) -> None:
        """Add a trajectory next to the current one and make it current."""
        doc = self.ctx.doc
        if not doc.plans:
            return
        plan, where = planning.new_trajectory(doc.plans, doc.current)
        if doc.add_plan(plan):
            self.ctx.status(f"added {plan.name!r} {where}: drag its entry and target into place")

    def remove_trajectory(self) -> None:
        """Remove the current trajectory."""
        doc = self.ctx.doc
        if doc.plan is not None:
            name = doc.plan.name
            if doc.remove_plan(doc.current):
                self.ctx.status(f"removed {name!r} (Edit > Undo brings it back)")

    def _edit_name(self) -> None:
        item = self.list.currentItem()
        if item is not None:
            self._updating = True
            try:
                item.setText(str(item.data(Qt.ItemDataRole.UserRole)))  # edit the bare name
            finally:
                self._updating = False
            self.list.editItem(item)

    def _renamed(self, item: QListWidgetItem) -> None:
        if not self._updating:  # applied once the editor is gone (see __init__)
            row, text = self.list.row(item), item.text()
            QTimer.singleShot(0, lambda: self._rename(row, text))

    def _rename(self, row: int, text: str) -> None:
        doc = self.ctx.doc
        if not 0 <= row < len(doc.plans):
            return
        if text == trajectory_label(row, doc.plans[row]) or text == doc.plans[row].name:
            self.refresh()  # not changed (or only the label shown again)
            return
        try:
            plan = planning.rename(doc.plans, row, text)
        except ValueError as exc:
            doc.edit_refused.emit(f"error: {exc}")
            self.refresh()
            return
        if row != doc.current:
            doc.select(row)
        if not doc.set_plan(plan):
            self.refresh()

    def rename_current(self, name: str) -> bool:
        """Rename the current trajectory (as the list's editor does)."""
        doc = self.ctx.doc
        try:
            plan = planning.rename(doc.plans, doc.current, name)
        except ValueError as exc:
            doc.edit_refused.emit(f"error: {exc}")
            return False
        return doc.set_plan(plan)
