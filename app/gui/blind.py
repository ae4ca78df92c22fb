"""A blind trial in the window: the exercise hides what would give the bone away.

When the plan opened is a blind trial's (``ctdrill exercise bone-quality``: a ``trial.json``
beside it, :func:`ctdrill.app.exercise.trials.find_trial`), the window shows the Rehearsal tab
and the banner (the plan's safety problems) alone: the CT views (3D, slices, panorama), the
plots (the HU profile with its Misch labels, the predicted force), the plan, suggestion,
series and debrief pages are hidden and a note stands in their place; the rehearsal panel
gives no prediction of the push and its live words name no force the bone resists with
(:mod:`ctdrill.app.gui.blind_words`). The session's summary and export hide the bone as the
command line does. Opening a plan that is no trial shows everything again.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel, QSplitter, QTabWidget, QWidget

from ctdrill.app.gui.views import VIEWS

if TYPE_CHECKING:
    from ctdrill.app.exercise.aids import AidLevel
    from ctdrill.app.exercise.trials import TrialCard

#: Views a blind trial shows (every other is hidden): the rehearsal and the banner (the plan's
#: safety problems, which say nothing of the bone).
BLIND_SHOWN = frozenset({"rehearsal", "banner"})
#: What stands where the hidden views were.
BLIND_NOTE = (
    "Blind trial {trial}: the CT views, the plots and the model's forecasts are hidden.\n\n"
    "Drill the site on the Rehearsal tab and feel the bone: how hard the drill pushes back, "
    "how fast it goes down, where it gives.\nThen name the bone's class under \"Name the "
    'bone" (or export the session: ctdrill assess SESSION --answer CLASS ...).'
)


class BlindWindow(Protocol):
    """What :func:`apply_blind` needs of the main window."""

    views: dict[str, QWidget]
    tabs: QTabWidget
    pages: QTabWidget
    blind_trial: TrialCard | None

    @property
    def volume_path(self) -> str: ...

    def setWindowTitle(self, title: str) -> None: ...

    def _status(self, text: str) -> None: ...


def apply_blind(window: BlindWindow, card: TrialCard | None) -> None:
    """Enter a blind trial (``card``) or leave it (None): module docstring."""
    blind = card is not None
    window.blind_trial = card
    for spec in VIEWS:
        if spec.key in BLIND_SHOWN:
            continue
        widget = window.views[spec.key]
        if spec.area == "tab":
            window.tabs.setTabVisible(window.tabs.indexOf(widget), not blind)
        elif spec.area == "page":
            window.pages.setTabVisible(window.pages.indexOf(widget), not blind)
        else:
            widget.setVisible(not blind)
    window.pages.setVisible(not blind)  # the 3D and slice views' page, and the others
    note = _note(window)
    if note is not None:
        note.setText("" if card is None else BLIND_NOTE.format(trial=card.trial))
        note.setVisible(blind)
    panel = window.views["rehearsal"]
    set_blind = getattr(panel, "set_blind", None)
    if set_blind is not None:
        set_blind(card)
    if card is not None:
        window.tabs.setCurrentWidget(panel)
        window.setWindowTitle(f"ctdrill: blind trial {card.trial}")
    else:
        window.setWindowTitle("ctdrill")


def _note(window: BlindWindow) -> QLabel | None:
    """The label standing where the hidden views were (made on first use, beside them)."""
    found = window.pages.parentWidget()
    if not isinstance(found, QSplitter):
        return None
    for i in range(found.count()):
        widget = found.widget(i)
        if isinstance(widget, QLabel) and widget.objectName() == "blind:note":
            return widget
    note = QLabel()
    note.setObjectName("blind:note")
    note.setWordWrap(True)
    note.setAlignment(Qt.AlignmentFlag.AlignCenter)
    note.setStyleSheet("font-size: 15px; color: #37474f; padding: 40px")
    note.setVisible(False)
    found.addWidget(note)
    return note


def show_trial(window: BlindWindow, paths: Sequence[str | os.PathLike[str]]) -> None:
    """Enter the blind trial whose plan is ``paths`` (a ``trial.json`` beside it), or leave
    blind mode for any other plan; a card that cannot be read is said on the status line."""
    from ctdrill.app.exercise.blind import window_trial
    from ctdrill.app.exercise.trials import TrialError

    try:  # a plan opened on a trial's CT stays blind too
        ct = window.volume_path or None
        card = window_trial([Path(p) for p in paths], Path(ct) if ct else None)
    except TrialError as exc:
        card = None
        window._status(f"not a blind trial: {exc}")
    apply_blind(window, card)


def apply_aids(window: BlindWindow, level: AidLevel | None) -> None:
    """The stop-yourself exercise's level in the window: its plots shown only where the level
    keeps them (a blind trial keeps them hidden whatever the level)."""
    shown = window.blind_trial is None and (level is None or level.plots)
    window.views["plots"].setVisible(shown)


def refuse_trial_ct(window: Any, ct: Path) -> bool:
    """True (the window said why on its status line and ``load_failed``) when ``ct`` is a
    blind trial's CT the window may not open: outside its own blind trial, unless the window
    was opened with the instructor's key (:func:`ctdrill.app.exercise.blind.check_window_ct`)."""
    from ctdrill.app.exercise.blind import check_window_ct

    if window.instructor:
        return False
    try:
        check_window_ct(ct, window.blind_trial)
    except ValueError as exc:
        window.last_error = str(exc)
        window._status(f"error: {exc}")
        window.load_failed.emit(str(exc))
        return True
    return False
