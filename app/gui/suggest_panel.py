"""The *Suggest* tab: search nearby axes (``ctdrill suggest``) and adopt one with a click.

The panel asks the document for a search (the controller runs it off the UI thread), shows
the best feasible candidates in a table (the 3D view draws them as numbered lines) and adopts
the one whose *Adopt* button is clicked: the document's plan takes its axis, everything else
kept. Numbers come from :mod:`ctdrill.app.gui.suggesting` (no logic here).
"""

from __future__ import annotations

import math
from functools import partial

from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QFormLayout,
    QHeaderView,
    QLabel,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.suggesting import row, summary_text, top_rows
from ctdrill.app.search.candidates import MAX_CONE_DEG, MAX_COUNT, MAX_RADIUS_MM, SearchSpace
from ctdrill.app.search.defaults import DEFAULT_CONE_DEG, DEFAULT_COUNT, DEFAULT_RADIUS_MM
from ctdrill.app.search.suggest import Suggestion

#: Table columns; the first holds each row's *Adopt* button (visible without scrolling).
COLUMNS = ("", "#", "score", "body HU", "crest", "apex", "offset", "tilt", "clearance")


def _num(value: float, fmt: str) -> str:
    return "-" if math.isnan(value) else fmt.format(value)


class SuggestPanel(QWidget):
    """Search settings, the *Suggest* button, the top candidates with an *Adopt* button each."""

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        outer = QVBoxLayout(self)
        form = QFormLayout()
        self.radius = QDoubleSpinBox()
        self.radius.setRange(0.0, MAX_RADIUS_MM)
        self.radius.setValue(DEFAULT_RADIUS_MM)
        self.radius.setSuffix(" mm")
        self.cone = QDoubleSpinBox()
        self.cone.setRange(0.0, MAX_CONE_DEG)
        self.cone.setValue(DEFAULT_CONE_DEG)
        self.cone.setSuffix(" deg")
        self.count = QSpinBox()
        self.count.setRange(1, MAX_COUNT)
        self.count.setValue(DEFAULT_COUNT)
        form.addRow("entry within", self.radius)
        form.addRow("tilt within", self.cone)
        form.addRow("candidates", self.count)
        outer.addLayout(form)
        self.button = QPushButton("Suggest axes")
        self.button.setToolTip(
            "Search axes around the plan: bone engagement under every margin (docs/suggest.md)"
        )
        self.button.clicked.connect(self.start)
        outer.addWidget(self.button)
        self.status = QLabel("Open a series and a plan, then search nearby axes.")
        self.status.setWordWrap(True)
        outer.addWidget(self.status)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.verticalHeader().setVisible(False)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        self.table.setToolTip(
            "the best distinct axes (# is the rank in candidates.csv; an axis whose entry and "
            "target both lie within a drill diameter of a better one's is not listed); "
            "crest/apex: fraction of the 2 mm zone in cortical bone; offset: entry move; "
            "tilt: from the planned axis; clearance: smallest to any landmark"
        )
        outer.addWidget(self.table, 1)  # the table takes the tab's height: every row shows
        #: Each shown row's button, and whether its axis is the plan's now.
        self.adopt_buttons: list[tuple[QPushButton, bool]] = []
        doc = ctx.doc
        doc.suggestion_changed.connect(self._changed)
        doc.plan_changed.connect(lambda _plan: self._enable())
        doc.volume_changed.connect(lambda _volume: self._enable())
        doc.rehearsal_changed.connect(lambda _running: self._enable())
        self._enable()

    def space(self) -> SearchSpace:
        """The search the settings describe."""
        return SearchSpace(
            radius_mm=self.radius.value(), cone_deg=self.cone.value(), count=self.count.value()
        )

    def start(self) -> bool:
        """Ask the document for a search with the panel's settings."""
        return self.ctx.doc.request_suggestion(self.space())

    def _enable(self) -> None:
        doc = self.ctx.doc
        ready = doc.volume is not None and doc.plan is not None and not doc.rehearsing
        self.button.setEnabled(ready and doc.suggest_status != "running")
        for button, current in self.adopt_buttons:
            button.setEnabled(not current and not doc.rehearsing)

    def _changed(self, suggestion: Suggestion | None) -> None:
        doc = self.ctx.doc
        self._enable()
        if suggestion is None:
            self._fill(None)
            if doc.suggest_status == "running":
                self.status.setText(f"searching {self.count.value()} axes ...")
                self.ctx.status("searching nearby axes ...")
            elif doc.suggest_status:
                self.status.setText(doc.suggest_status)
            return
        self._fill(suggestion)
        text = summary_text(suggestion)
        if doc.adopted is not None:
            text += f" Adopted candidate {doc.adopted}."
        self.status.setText(text)
        self.ctx.status(text)

    def _fill(self, s: Suggestion | None) -> None:
        rows = () if s is None else top_rows(s)
        if s is not None and all(r.index != 0 for r in rows):
            rows = (*rows, row(s, 0))  # the planned axis: its rank, and the way back to it
        self.table.setRowCount(len(rows))
        self.adopt_buttons = []
        adopted = self.ctx.doc.adopted
        for r, shown in enumerate(rows):
            cells = (
                "plan" if shown.index == 0 else str(shown.rank),
                _num(shown.score, "{:.3f}"),
                _num(shown.body_hu, "{:.0f}"),
                _num(shown.crest_cortical, "{:.2f}"),
                _num(shown.apex_cortical, "{:.2f}"),
                f"{shown.offset_mm:.2f} mm",
                f"{shown.tilt_deg:.1f}\N{DEGREE SIGN}",
                _num(shown.min_clearance_mm, "{:.2f} mm"),
            )
            for c, text in enumerate(cells, start=1):
                item = QTableWidgetItem(text)
                if shown.index == 0:
                    item.setToolTip(f"the planned axis (candidate 0), rank {shown.rank}")
                self.table.setItem(r, c, item)
            label = "adopted" if shown.index == adopted else "Adopt"
            if shown.index == 0:
                label = "current" if adopted in (None, 0) else "Back"
            button = QPushButton(label)
            current = shown.index == adopted or (shown.index == 0 and adopted is None)
            button.setEnabled(not current and not self.ctx.doc.rehearsing)
            button.clicked.connect(partial(self.adopt, shown.index))
            self.table.setCellWidget(r, 0, button)
            self.adopt_buttons.append((button, current))

    def adopt(self, index: int, _checked: bool = False) -> None:
        """Make candidate ``index`` the plan's axis."""
        if self.ctx.doc.adopt_candidate(index):
            self.ctx.status(f"adopted suggested axis {index}: the path is recomputed")
