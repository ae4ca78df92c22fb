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
from PySide6.QtWidgets import QCheckBox, QComboBox, QLabel

from ctdrill.app.exercise.aids import AID_LEVELS, AidLevel, aid_level
from ctdrill.app.gui.blind_words import BLIND_PREDICTION
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

    def update_exam_toggle(self) -> None: ...


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

    def prediction(self) -> str | None:
        """What the panel says instead of the push's prediction (None: the prediction)."""
        return BLIND_PREDICTION if self.card is not None else None
