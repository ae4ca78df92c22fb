"""A blind bone-quality trial in the window, driven with real Qt events: the CT views, the
plots (HU, Misch labels, the predicted force) and the push's prediction are hidden; nothing on
screen names the class, a CT number or a prediction; the export is answered with ctdrill assess."""

from __future__ import annotations

import json
import re
import sqlite3
from pathlib import Path

import pytest
from PySide6.QtCore import QPoint, Qt
from PySide6.QtWidgets import (
    QAbstractButton,
    QComboBox,
    QLabel,
    QLineEdit,
    QTabBar,
    QWidget,
)
from pytestqt.qtbot import QtBot

from ctdrill.app.cli import main
from ctdrill.app.exercise.bone_quality import TRIAL_CLASSES, write_bone_quality
from ctdrill.app.exercise.trials import BLIND_HIDDEN_KEYS
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.rehearsal import SIMULATOR
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

SESSION_MS = 90_000
#: What must not be on screen in a blind trial: a class, a CT number, a prediction.
GIVEAWAY = re.compile(
    r"\bD[1-5]\b|misch|\bHU\b|predict|needed to cut|\bS0\b|cortical|trabecular", re.IGNORECASE
)


def _screen_text(window: MainWindow, *, skip: QWidget | None = None) -> list[str]:
    """Every text a visible widget of the window shows (labels, buttons, fields, tabs, the
    title and the status line), but those inside ``skip``."""
    out = [window.windowTitle(), window.statusBar().currentMessage()]
    for w in window.findChildren(QWidget):
        if not w.isVisible() or (skip is not None and skip.isAncestorOf(w)):
            continue
        if isinstance(w, QLabel | QAbstractButton | QLineEdit):
            out.append(w.text())
        elif isinstance(w, QComboBox):
            out.append(w.currentText())
        elif isinstance(w, QTabBar):
            out += [w.tabText(i) for i in range(w.count()) if w.isTabVisible(i)]
    return [t for t in out if t]


def _assert_blind(window: MainWindow, truth: str = "") -> None:
    """No class, CT number or prediction on screen but the trainee's own answer (in the
    answer box); the true class nowhere at all."""
    own = window.rehearsal.exercise.answer_box
    shown = [t for t in _screen_text(window, skip=own) if GIVEAWAY.search(t)]
    assert shown == [], shown
    if truth:
        assert not [t for t in _screen_text(window) if re.search(rf"\b{truth}\b", t)]
    for w in window.findChildren(QWidget):
        name = w.objectName()
        if name.startswith(("view:", "plot:")):
            assert not w.isVisible(), name
    for view in (window.view3d, window.slice_grid, window.plot_canvas, window.pages):
        assert not view.isVisible()


@pytest.mark.timeout(240)
def test_a_trainee_drills_a_blind_trial_with_the_mouse(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    trials = write_bone_quality(tmp_path / "trials", trials=1, seed=4, spacing_mm=0.5)
    trial = tmp_path / "trials" / "trial-01"
    window.resize(1280, 800)
    window.show()
    qtbot.waitExposed(window, timeout=LOAD_TIMEOUT_MS)
    window.open_plan(trial / "plan.json")
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(trial / "ct")
    panel = window.rehearsal
    assert window.tabs.currentWidget() is panel and "blind trial trial-01" in window.windowTitle()
    _assert_blind(window)
    window.grab().save(str(tmp_path / "blind-before.png"))
    panel.duration_s = 120.0  # ends at the auto-stop
    assert panel.device.currentText() == SIMULATOR
    hand = panel.hand
    pos = QPoint(hand.width() // 2, round(hand.y_of(14.0)))
    qtbot.mousePress(hand, Qt.MouseButton.LeftButton, pos=pos)  # a real press sets the push
    qtbot.mouseRelease(hand, Qt.MouseButton.LeftButton, pos=pos)
    assert hand.push_n == pytest.approx(14.0, abs=0.5)
    qtbot.mouseClick(panel.connect_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(
        lambda: panel.last is not None and panel.last.drill_mm > 1.0, timeout=SESSION_MS
    )
    _assert_blind(window)  # while it cuts
    assert panel.hand.need_n is None
    window.grab().save(str(tmp_path / "blind-cutting.png"))
    qtbot.waitUntil(lambda: panel.run is not None and not panel.run.running, timeout=SESSION_MS)
    box = panel.exercise
    qtbot.waitUntil(panel.end_reported, timeout=LOAD_TIMEOUT_MS)  # its debrief made (a worker)
    # an answer given before then waits for it, and says so (not "drill the trial first")
    panel.end_reported = lambda: False  # type: ignore[method-assign]
    assert not box.record_answer()
    assert "still being summarised" in box.answer_message.text()
    del panel.end_reported
    assert panel.end_reported()
    _assert_blind(window, trials[0].misch)  # and at the end (the debrief page stays hidden)
    window.grab().save(str(tmp_path / "blind-end.png"))
    files = panel.export(tmp_path / "export")
    names = sorted(f.name for f in files)  # display.csv: what the window showed, and when
    assert names in (
        ["session.csv", "summary.json", "table.json"],
        ["display.csv", "session.csv", "summary.json", "table.json"],
    )
    summary = json.loads((tmp_path / "export" / "session" / "summary.json").read_text())
    assert summary["exercise"]["trial"] == "trial-01"
    assert not re.search(r"\bD[1-5]\b|misch", json.dumps(summary), re.IGNORECASE)
    assert not set(summary) & BLIND_HIDDEN_KEYS
    table = (tmp_path / "export" / "session" / "table.json").read_text()
    assert "table_sealed" in json.loads(table) and "s0_n" not in table  # forces sealed
    assert not re.search(r"\bD[1-5]\b|misch", table, re.IGNORECASE)
    db = tmp_path / "record.db"
    named = next(c for c in TRIAL_CLASSES if c != trials[0].misch)
    assert (
        main(
            [
                "assess",
                str(tmp_path / "export"),
                "--answer",
                named,
                "--db",
                str(db),
                "--trainee",
                "ann",
            ]
        )
        == 0
    )
    with sqlite3.connect(db) as conn:
        assert conn.execute("SELECT answer, truth FROM answers").fetchall() == [
            (named, trials[0].misch)
        ]
    # the window names the bone too: real clicks and keys into the answer box
    assert box.answer_box.isVisible()
    wrong = next(c for c in TRIAL_CLASSES if c not in (trials[0].misch, named))
    box.answer.setFocus()
    for _ in range(TRIAL_CLASSES.index(wrong) + 1):
        qtbot.keyClick(box.answer, Qt.Key.Key_Down)
    assert box.answer.currentText() == wrong
    qtbot.keyClicks(box.answer_db, str(tmp_path / "window.db"))
    qtbot.keyClicks(box.answer_trainee, "Bo")
    qtbot.mouseClick(box.answer_button, Qt.MouseButton.LeftButton)
    assert box.answer_message.text() == f"Recorded: trial-01, your answer {wrong}."
    _assert_blind(window, trials[0].misch)  # the answer recorded, the class still hidden
    window.grab().save(str(tmp_path / "blind-answered.png"))
    box.answer_box.grab().save(str(tmp_path / "blind-answer-box.png"))
    with sqlite3.connect(tmp_path / "window.db") as conn:
        rows = conn.execute(
            "SELECT s.trainee, a.answer, a.truth FROM answers a JOIN sessions s USING "
            "(session_hash)"
        ).fetchall()
    assert rows == [("bo", wrong, trials[0].misch)]
    # a plan that is no trial, opened on the trial's CT, keeps the window blind
    window.open_plan(phantom_case.plan_path)
    assert window.blind_trial is not None and not window.pages.isVisible()
    # on a CT that is no trial's, it shows everything again (waited for until that CT is loaded
    # and its path drawn: the path of the plan just opened on the trial's CT may come first)
    trial_ct = window.doc.volume
    window.open_folder(phantom_case.ct_dir)

    def opened() -> bool:
        doc = window.doc
        return doc.volume is not trial_ct and doc.path is not None and doc.path.plan is doc.plan

    qtbot.waitUntil(opened, timeout=LOAD_TIMEOUT_MS)
    window.open_plan(phantom_case.plan_path)
    assert window.windowTitle() == "ctdrill" and window.pages.isVisible()
    assert window.plot_canvas.isVisible()


@pytest.mark.timeout(240)
def test_the_aids_fade_level_by_level(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    from tests.app.gui.helpers import open_case

    window.resize(1280, 800)
    window.show()
    qtbot.waitExposed(window, timeout=LOAD_TIMEOUT_MS)
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    window.tabs.setCurrentWidget(panel)
    picker = panel.exercise.picker
    live = panel.live
    seen = []
    for _ in range(picker.count() - 1):  # the keyboard walks the list: all aids to none
        picker.setFocus()
        qtbot.keyClick(picker, Qt.Key.Key_Down)
        level = panel.exercise.level
        assert level is not None
        seen.append(level.name)
        assert window.plot_canvas.isVisible() == level.plots
        assert live.clearance_label.isVisible() == level.clearance
        assert live.forces.isVisible() == live.depth_gauge.isVisible() == level.gauges
        assert panel.exam.isChecked() or level.wall
        assert panel.exam.isEnabled() == level.wall
    assert seen == ["all-aids", "no-plots", "no-readout", "no-gauges", "no-wall"]
    window.grab().save(str(tmp_path / "no-wall.png"))
    qtbot.keyClick(picker, Qt.Key.Key_Up)  # no-gauges: the wall is back
    assert panel.exercise.level is not None and panel.exercise.level.name == "no-gauges"
    qtbot.mouseClick(panel.exam, Qt.MouseButton.LeftButton)  # exam off again
    assert not panel.exam.isChecked()
    panel.duration_s = 120.0
    pos = QPoint(panel.hand.width() // 2, round(panel.hand.y_of(16.0)))
    qtbot.mousePress(panel.hand, Qt.MouseButton.LeftButton, pos=pos)
    qtbot.mouseRelease(panel.hand, Qt.MouseButton.LeftButton, pos=pos)
    qtbot.mouseClick(panel.connect_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: panel.run is not None and not panel.run.running, timeout=SESSION_MS)
    window.grab().save(str(tmp_path / "no-gauges-end.png"))
    assert panel.run is not None
    summary = panel.run.summary()
    assert summary["mode"] == "stop-yourself:no-gauges"
    assert summary["aids"] == {"level": "no-gauges", "on": ["wall"]}
    qtbot.keyClick(picker, Qt.Key.Key_Home)  # a free rehearsal shows everything again
    assert panel.exercise.level is None and window.plot_canvas.isVisible()
    assert live.forces.isVisible() and live.clearance_label.isVisible()
