"""The debrief page's replay is built when the page is shown: a session that ends while it is
hidden costs the UI thread no figure, and the page then shows what it would have shown."""

from __future__ import annotations

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.debrief import Debrief
from ctdrill.app.gui.debrief_view import DebriefView
from ctdrill.app.gui.document import Document, ViewContext
from ctdrill.app.gui.workers import StepQueue
from tests.app.test_trainee_words import GUARDED

pytestmark = pytest.mark.gui


def _debrief() -> Debrief:
    t = np.linspace(0.0, 3.0, 301)
    drill = np.minimum(4.0 * t, 10.8)
    summary = {"assessment": GUARDED, "planned_depth_mm": 12.6, "max_safe_depth_mm": 10.8}
    return Debrief("{}", "", "{}", summary, t, drill + 0.2, drill, 3.0 + 2.0 * np.sin(t))


def _view(qtbot: QtBot) -> tuple[DebriefView, Document]:
    doc = Document()
    view = DebriefView(ViewContext(doc, StepQueue(), lambda _text: None))
    qtbot.addWidget(view)
    view.resize(700, 420)
    return view, doc


def _pixels(qtbot: QtBot, view: DebriefView) -> np.ndarray:
    qtbot.waitUntil(lambda: not view.canvas._draw_pending, timeout=5000)
    view.canvas.draw()
    return np.asarray(view.canvas.buffer_rgba()).copy()


def test_the_replay_waits_for_the_page_and_is_then_what_a_shown_page_draws(
    qtbot: QtBot,
) -> None:
    debrief = _debrief()
    shown, shown_doc = _view(qtbot)  # on screen when the session ends: drawn at once
    shown.show()
    qtbot.waitExposed(shown)
    shown_doc.set_debrief(debrief)
    assert not shown.replay_due and len(shown.figure.axes) == 2
    hidden, hidden_doc = _view(qtbot)  # hidden when it ends: its words, no figure
    hidden_doc.set_debrief(debrief)
    assert hidden.replay_due and hidden.figure.axes == []
    assert hidden.cursor_label.text() == shown.cursor_label.text() != "-"
    assert [w.text() for w in hidden.line_labels] == [w.text() for w in shown.line_labels]
    hidden.show()  # the page comes on screen: the replay, the cursor where the scrub is
    qtbot.waitUntil(lambda: not hidden.replay_due, timeout=5000) and len(hidden.figure.axes) == 2
    cursor = [ax.lines[-1].get_xdata() for ax in hidden.figure.axes]
    assert all(np.allclose(x, [3.0, 3.0]) for x in cursor)
    # the same picture as the page on screen gives, its layout made at the page's size (the
    # shown page laid its figure out before the words beside it took their room)
    assert hidden.canvas.size() == shown.canvas.size()
    shown._redraw()
    shown._scrubbed(shown.scrub.value())
    np.testing.assert_array_equal(_pixels(qtbot, hidden), _pixels(qtbot, shown))
