"""The debrief page: how the last rehearsal went in plain words, its replay (scrub through time:
depth, force and the hand's position), an expert session of the same plan laid over it, and
the trainee record (the SQLite file ``ctdrill assess`` reads and writes).

It observes the document's debrief (:meth:`ctdrill.app.gui.document.Document.set_debrief`,
set by the rehearsal panel when a session ends); the work is headless
(:mod:`ctdrill.app.gui.debrief`, :mod:`ctdrill.app.trainee`). The replay's figure is built
when the page is on screen: a session that ends while the page is hidden (the usual case:
the rehearsal's tab is in front) costs the UI thread its words, not the figure's layout and
Agg draw (~100 ms of matplotlib); the page draws it when it is shown.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import Qt
from PySide6.QtGui import QShowEvent
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSlider,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.errors import AppInputError
from ctdrill.app.gui.debrief import Debrief, best_expert, draw_replay
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.plots import WINDOW_DPI
from ctdrill.app.trainee.kinds import mode_of
from ctdrill.app.trainee.record import check_trainee, open_record
from ctdrill.app.trainee.words import debrief_lines

#: Slider steps over a session (the replay's resolution).
SCRUB_STEPS = 1000


class DebriefView(QWidget):
    """The debrief (module docstring)."""

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.debrief: Debrief | None = None
        self.expert: dict[str, np.ndarray] | None = None
        self._cursors: list[Any] = []
        #: The replay's figure waits for the page to be shown (:meth:`showEvent`).
        self.replay_due = False
        outer = QHBoxLayout(self)
        left = QVBoxLayout()
        outer.addLayout(left, 2)
        self.title = QLabel("No rehearsal yet: run one from the Rehearsal tab.")
        self.title.setStyleSheet("font-size:14pt; font-weight:bold")
        self.title.setWordWrap(True)
        left.addWidget(self.title)
        self.lines_box = QVBoxLayout()
        left.addLayout(self.lines_box)
        self.line_labels: list[QLabel] = []

        rec = QGroupBox("Trainee record")
        form = QFormLayout(rec)
        self.db_edit = QLineEdit()
        self.db_edit.setPlaceholderText("a .sqlite file (ctdrill assess --db)")
        browse = QPushButton("Browse...")
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.db_edit, 1)
        row.addWidget(browse)
        form.addRow("file", row)
        self.trainee_edit = QLineEdit()
        self.trainee_edit.setPlaceholderText("your name or student number")
        form.addRow("trainee", self.trainee_edit)
        self.expert_box = QCheckBox("this is an expert's session")
        form.addRow(self.expert_box)
        self.save_button = QPushButton("Save to the record")
        self.save_button.clicked.connect(self.save)
        self.compare_button = QPushButton("Compare with an expert")
        self.compare_button.clicked.connect(self.compare)
        buttons = QHBoxLayout()
        buttons.addWidget(self.save_button)
        buttons.addWidget(self.compare_button)
        form.addRow(buttons)
        self.record_message = QLabel("")
        self.record_message.setWordWrap(True)
        form.addRow(self.record_message)
        left.addWidget(rec)
        left.addStretch(1)

        right = QVBoxLayout()
        outer.addLayout(right, 3)
        self.figure = Figure(figsize=(6, 4), dpi=WINDOW_DPI)
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setObjectName("plot:replay")
        right.addWidget(self.canvas, 1)
        self.scrub = QSlider(Qt.Orientation.Horizontal)
        self.scrub.setRange(0, SCRUB_STEPS)
        self.scrub.setToolTip("Drag to replay the session: the cursor moves through time")
        self.scrub.valueChanged.connect(self._scrubbed)
        right.addWidget(self.scrub)
        self.cursor_label = QLabel("-")
        self.cursor_label.setWordWrap(True)
        right.addWidget(self.cursor_label)
        ctx.doc.debrief_changed.connect(self.show_debrief)
        self.show_debrief(None)

    # ------------------------------------------------------------------ showing
    def show_debrief(self, debrief: object) -> None:
        """Show a session's debrief (None: none yet)."""
        self.debrief = debrief if isinstance(debrief, Debrief) else None
        self.expert = None
        for label in self.line_labels:
            label.deleteLater()
        self.line_labels = []
        d = self.debrief
        enabled = d is not None
        self.save_button.setEnabled(enabled)
        self.compare_button.setEnabled(enabled)
        self.scrub.setEnabled(enabled)
        if d is None:
            self._redraw()
            return
        exam = d.summary.get("exam", {}).get("enabled", False)
        self.title.setText("How it went" + (" (exam: no wall at the margin)" if exam else ""))
        lines = debrief_lines(d.assessment, planned_depth_mm=d.planned_depth_mm, summary=d.summary)
        for line in lines:
            label = QLabel(line.text)
            label.setWordWrap(True)
            label.setToolTip(line.tooltip(d.assessment))
            if line is not None and line.bad:
                label.setStyleSheet("color:#c62828; font-weight:bold")
            self.lines_box.addWidget(label)
            self.line_labels.append(label)
        self.line_labels[0].setStyleSheet("font-size:13pt; font-weight:bold")
        self.record_message.setText("")
        self._redraw()
        self.scrub.setValue(SCRUB_STEPS)
        self._scrubbed(self.scrub.value())

    def _redraw(self) -> None:
        if not self.isVisible():  # a hidden page: built and drawn when it is shown
            self.replay_due = True
            return
        self.replay_due = False
        axes = draw_replay(self.figure, self.debrief, cursor_s=0.0, expert=self.expert)
        self._cursors = [] if axes is None else [ax.lines[-1] for ax in axes]
        self.canvas.draw_idle()

    def showEvent(self, event: QShowEvent) -> None:
        """The page comes on screen: the replay waiting for it is built in the next drawing
        step (laid out at the page's size, the cursor where the scrub is)."""
        super().showEvent(event)
        if self.replay_due:
            self.ctx.steps.push(self._build_due)

    def _build_due(self) -> None:
        if self.replay_due and self.isVisible():
            self._redraw()
            self._scrubbed(self.scrub.value())

    def cursor_s(self) -> float:
        """The replay's time, s."""
        d = self.debrief
        if d is None or d.time_s.size == 0:
            return 0.0
        return float(d.time_s[0] + (d.time_s[-1] - d.time_s[0]) * self.scrub.value() / SCRUB_STEPS)

    def _scrubbed(self, _value: int) -> None:
        d = self.debrief
        if d is None:
            self.cursor_label.setText("-")
            return
        t = self.cursor_s()
        self.cursor_label.setText(d.cursor_text(d.index_at(t)))
        if self.replay_due:  # the replay is built when the page is shown, cursor there
            return
        for line in self._cursors:
            line.set_xdata([t, t])
        self.canvas.draw_idle()

    # ------------------------------------------------------------------ the record
    def _browse(self) -> None:
        path, _ = QFileDialog.getSaveFileName(
            self,
            "Trainee record",
            self.db_edit.text(),
            "SQLite (*.sqlite *.db);;All (*)",
            options=QFileDialog.Option.DontConfirmOverwrite,
        )
        if path:
            self.db_edit.setText(path)

    def _db(self) -> Path | None:
        text = self.db_edit.text().strip()
        if not text:
            self.record_message.setText("Choose the record's file first.")
            return None
        return Path(text)

    def save(self) -> bool:
        """Store the session in the record (as ``ctdrill assess`` stores its folder)."""
        d, db = self.debrief, self._db()
        if d is None or db is None:
            return False
        try:
            trainee = check_trainee(self.trainee_edit.text())
            entry = d.entry()
            record = open_record(db, create=True)
            try:
                stored = record.store(entry, trainee=trainee, expert=self.expert_box.isChecked())
            finally:
                record.close()
        except AppInputError as exc:
            self.record_message.setText(f"Not saved: {exc}")
            return False
        what = "Saved" if stored else "Already in the record"
        self.record_message.setText(f"{what}: session {entry.session_hash[:12]} in {db.name}.")
        return stored

    def compare(self) -> bool:
        """Lay the best expert session of the same plan over the replay."""
        d, db = self.debrief, self._db()
        if d is None or db is None:
            return False
        try:
            record = open_record(db, create=False)
            try:
                found = best_expert(
                    record,
                    str(d.summary["plan_sha256"]),
                    exclude=d.entry().session_hash,
                    mode=mode_of(d.summary),
                )
            finally:
                record.close()
        except AppInputError as exc:
            self.record_message.setText(f"No comparison: {exc}")
            return False
        if found is None:
            self.record_message.setText(
                "The record holds no expert session of this case and mode yet."
            )
            return False
        row, self.expert = found
        self._redraw()
        self._scrubbed(self.scrub.value())
        self.record_message.setText(
            f"Dashed grey: {row['trainee']}'s session (score {row['score']:.0f}) on the same plan."
        )
        return True
