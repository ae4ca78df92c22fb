"""The rehearsal panel's exercises: a blind trial (:mod:`ctdrill.app.gui.blind`) and the
stop-yourself exercise's aid levels (:mod:`ctdrill.app.exercise.aids`).

The "exercise" list picks a free rehearsal or a level from all aids to none. A level hides
what it takes away: the plots (the window's, :data:`aids_changed` tells it), the clearance
readout, the gauges (forces, depth, vibration), and at ``no-wall`` it turns exam mode on and
locks it. The session's summary then carries the level (``mode``, ``aids``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QGroupBox,
    QLabel,
    QLineEdit,
    QPushButton,
)

from ctdrill.app.errors import AppInputError
from ctdrill.app.exercise.aids import AID_LEVELS, AidLevel, aid_level
from ctdrill.app.exercise.bone_quality import TRIAL_CLASSES
from ctdrill.app.gui.blind_words import BLIND_PREDICTION
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.rehearsal_live import LiveReadouts

if TYPE_CHECKING:
    from ctdrill.app.exercise.trials import TrialCard

#: The list's first entry: no exercise.
FREE = "free rehearsal"


class Panel(Protocol):
    """What the controls need of the rehearsal panel."""

    live: LiveReadouts
    exam: QCheckBox
    timing_label: QLabel

    ctx: ViewContext

    def update_exam_toggle(self) -> None: ...

    def end_reported(self) -> bool: ...


class ExerciseControls(QObject):
    """The panel's exercise state: the blind trial's card and the aid level (module docstring)."""

    aids_changed = Signal(object)  # the AidLevel, or None for a free rehearsal

    def __init__(self, panel: Panel) -> None:
        super().__init__()
        self.panel = panel
        self.card: TrialCard | None = None
        self.level: AidLevel | None = None
        self.picker = QComboBox()
        self.picker.setObjectName("exercise:aids")
        self.picker.addItem(FREE)
        for level in AID_LEVELS:
            self.picker.addItem(f"stop yourself: {level.name}")
        self.picker.setToolTip(
            "The stop-yourself exercise: the aids fade level by level (plots, clearance "
            "readout, gauges, then the wall); each level is an exercise with a pass mark "
            "(docs/exercises.md)"
        )
        self.picker.currentIndexChanged.connect(self._picked)
        self.answer_box = self._answer_box()

    def _picked(self, index: int) -> None:
        self.set_level(None if index <= 0 else aid_level(AID_LEVELS[index - 1].name))

    def set_level(self, level: AidLevel | None) -> None:
        """Rehearse at ``level`` (None: a free rehearsal)."""
        self.level = level
        live = self.panel.live
        live.clearance_label.setVisible(level is None or level.clearance)
        for gauge in (live.forces, live.depth_gauge, live.trace):
            gauge.setVisible(level is None or level.gauges)
        if level is not None and not level.wall:
            self.panel.exam.setChecked(True)
        self.panel.update_exam_toggle()
        self.aids_changed.emit(level)

    @property
    def exam_locked(self) -> bool:
        """The level takes the wall away: exam mode is on and cannot be turned off."""
        return self.level is not None and not self.level.wall

    def set_blind(self, card: TrialCard | None) -> None:
        """Drill a blind trial (``card``: no prediction, no word of the bone) or not (None)."""
        self.card = card
        self.panel.live.blind = card is not None
        self.panel.timing_label.setToolTip("")
        self.answer_box.setVisible(card is not None)
        self.answer_message.setText("")

    # ------------------------------------------------------------------ naming the bone
    def _answer_box(self) -> QGroupBox:
        """Name the bone of the blind trial just drilled, into the trainee record."""
        box = QGroupBox("Name the bone")
        box.setObjectName("exercise:answer")
        form = QFormLayout(box)
        self.answer = QComboBox()
        self.answer.addItems(["choose", *TRIAL_CLASSES])
        form.addRow("its class", self.answer)
        self.answer_db = QLineEdit()
        self.answer_db.setPlaceholderText("the trainee record's file (SQLite)")
        form.addRow("record", self.answer_db)
        self.answer_trainee = QLineEdit()
        self.answer_trainee.setPlaceholderText("your name or student number")
        form.addRow("trainee", self.answer_trainee)
        self.answer_button = QPushButton("Record my answer")
        self.answer_button.clicked.connect(self.record_answer)
        form.addRow(self.answer_button)
        self.answer_message = QLabel("")
        self.answer_message.setWordWrap(True)
        form.addRow(self.answer_message)
        box.setVisible(False)
        return box

    def record_answer(self) -> bool:
        """Store the session just drilled and the class named (as ``ctdrill assess --answer``
        does); the screen says it was recorded, never whether it was right."""
        from pathlib import Path

        from ctdrill.app.trainee.answers import answer_entries

        if not self.panel.end_reported():  # its debrief is made in a worker (tens of ms)
            self.answer_message.setText(
                "The session just drilled is still being summarised: record your answer in a "
                "moment."
            )
            return False
        debrief = self.panel.ctx.doc.debrief  # the last ended session's
        entry = getattr(debrief, "entry", None)
        if self.card is None or entry is None:
            self.answer_message.setText("Drill the trial first: nothing to answer yet.")
            return False
        if self.answer.currentIndex() <= 0 or not self.answer_db.text().strip():
            self.answer_message.setText("Choose the class and the record's file.")
            return False
        try:
            [(_e, _stored, answer, earlier)] = answer_entries(
                Path(self.answer_db.text().strip()),
                [entry()],
                [self.answer.currentText()],
                trainee=self.answer_trainee.text(),
            )
        except AppInputError as exc:
            self.answer_message.setText(f"Not recorded: {exc}")
            return False
        said = answer.answer if earlier is None else f"{earlier} (your first answer stands)"
        self.answer_message.setText(f"Recorded: {self.card.trial}, your answer {said}.")
        return True

    def prediction(self) -> str | None:
        """What the panel says instead of the push's prediction (None: the prediction)."""
        return BLIND_PREDICTION if self.card is not None else None
