"""A student without a robot: the hand driven by real mouse and key events, the live gauges, exam
mode, the debrief (replay, expert overlay) and the trainee record shared with ctdrill assess."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication, QWidget
from pytestqt.qtbot import QtBot

from ctdrill.app.cli import main
from ctdrill.app.gui.debrief_view import DebriefView
from ctdrill.app.gui.hand_control import HandControl
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.rehearsal import SIMULATOR
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

#: Longest wait for a realtime session, ms (a few seconds of device time, under load).
SESSION_MS = 90_000


def _press_at(qtbot: QtBot, hand: HandControl, push_n: float) -> None:
    qtbot.mousePress(
        hand, Qt.MouseButton.LeftButton, pos=QPoint(hand.width() // 2, round(hand.y_of(push_n)))
    )


def _wheel(widget: QWidget, notches: int) -> None:
    """A real wheel event: ``notches`` > 0 rolls down (towards the user)."""
    centre = QPointF(widget.width() / 2, widget.height() / 2)
    event = QWheelEvent(
        centre,
        widget.mapToGlobal(centre),
        QPoint(0, 0),
        QPoint(0, -120 * notches),
        Qt.MouseButton.NoButton,
        Qt.KeyboardModifier.NoModifier,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    QApplication.sendEvent(widget, event)


def test_the_hand_follows_the_mouse_the_wheel_and_the_keys(qtbot: QtBot) -> None:
    hand = HandControl()
    qtbot.addWidget(hand)
    hand.resize(100, 300)
    hand.show()
    qtbot.waitExposed(hand, timeout=LOAD_TIMEOUT_MS)
    pushes: list[float] = []
    hand.push_changed.connect(pushes.append)
    px = 40.0 / (300 - 18 - 34)  # newtons per pixel of the bar
    _press_at(qtbot, hand, 10.0)
    assert hand.push_n == pytest.approx(10.0, abs=px)
    assert hand.window().focusWidget() is hand  # the press takes the keyboard
    for y_push in (14.0, 20.0):  # dragging down pushes harder
        qtbot.mouseMove(hand, QPoint(50, round(hand.y_of(y_push))))
    qtbot.mouseRelease(hand, Qt.MouseButton.LeftButton, pos=QPoint(50, round(hand.y_of(20.0))))
    assert hand.push_n == pytest.approx(20.0, abs=px)
    start = hand.push_n
    _wheel(hand, 2)
    assert hand.push_n == pytest.approx(start + 1.0)
    _wheel(hand, -4)
    assert hand.push_n == pytest.approx(start - 1.0)
    qtbot.keyClick(hand, Qt.Key.Key_Down)
    qtbot.keyClick(hand, Qt.Key.Key_PageDown)
    assert hand.push_n == pytest.approx(start - 1.0 + 0.5 + 5.0)
    qtbot.keyClick(hand, Qt.Key.Key_Up)
    assert hand.push_n == pytest.approx(start + 4.0)
    qtbot.keyClick(hand, Qt.Key.Key_Space)
    assert hand.push_n == 0.0
    qtbot.keyClick(hand, Qt.Key.Key_Up)  # never below 0
    assert hand.push_n == 0.0 and pushes[-1] == 0.0
    with qtbot.waitSignal(hand.retract_requested, timeout=LOAD_TIMEOUT_MS):
        qtbot.keyClick(hand, Qt.Key.Key_R)
    assert hand.retracting
    assert len(pushes) >= 8 and all(0.0 <= p <= 78.0 for p in pushes)


def _shots(window: MainWindow, out: Path, name: str) -> None:
    window.grab().save(str(out / f"{name}.png"))
    panel = window.rehearsal
    panel.live.grab().save(str(out / f"{name}-hand-and-gauges.png"))


def _expert_session(case: PhantomCase, tmp_path: Path, db: Path) -> None:
    """An expert's session of the same plan, from the command line, into the record."""
    out = tmp_path / "expert"
    argv = ["rehearse", "--dicom", str(case.ct_dir), "--plan", str(case.plan_path)]
    argv += ["--out", str(out), "--operator", "human:force=14,react_ms=120", "--duration-s", "3"]
    assert main(argv) == 0
    assert main(["assess", str(out), "--db", str(db), "--trainee", "dr-expert", "--expert"]) == 0


@pytest.mark.timeout(240)
def test_a_student_drills_with_the_mouse_and_reads_the_debrief(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    window.tabs.setCurrentWidget(panel)
    panel.duration_s = 120.0  # the session ends at the auto-stop
    assert panel.device.currentText() == SIMULATOR
    hand = panel.hand
    _press_at(qtbot, hand, 6.0)  # too weak for the cortex: the screen says by how much
    qtbot.mouseRelease(
        hand, Qt.MouseButton.LeftButton, pos=QPoint(hand.width() // 2, round(hand.y_of(6.0)))
    )
    qtbot.mouseClick(panel.connect_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: "Push harder" in panel.status_label.text(), timeout=SESSION_MS)
    assert "N needed to cut here" in panel.status_label.text()
    assert panel.hand.need_n is not None and panel.hand.need_n > 6.0
    _shots(window, tmp_path, "too-weak")
    hand.setFocus()
    weak = hand.push_n
    for _ in range(3):
        qtbot.keyClick(hand, Qt.Key.Key_PageDown)  # 21 N: it cuts
    assert panel.run is not None and panel.run.push_n == pytest.approx(weak + 15.0)
    run = panel.run

    def cutting_hard() -> bool:
        last = panel.last
        return last is not None and last.state == "cutting" and panel.forces.forces["cutting"] > 10

    # The session runs at the wall clock's pace in its own process: a window starved of CPU
    # may first look after the drill has reached the stop (21 N takes about 1 s to it), so the
    # live cut is shown when the window sees it and the recorded session is checked after.
    qtbot.waitUntil(lambda: cutting_hard() or not run.running, timeout=SESSION_MS)
    if cutting_hard():
        _shots(window, tmp_path, "cutting")
    qtbot.waitUntil(
        lambda: run.assessment is not None and not window.doc.rehearsing, timeout=SESSION_MS
    )
    # the 21 N push cut: the device rendered more than 10 N of cutting force while cutting
    assert any(row[4] == "cutting" and row[3] > 10.0 for row in run.rows)
    assert run.assessment is not None and run.assessment["breach"] is False
    assert run.assessment["peak_hand_force_n"] > 15.0 and run.session is not None
    assert run.session["final_state"] == "stopped"
    # what the window showed, and when (the reaction is timed from it): every frame drawn at or
    # after its sample's time; the largest delay is in the assessment
    assert run.display and all(shown >= t for t, shown in run.display)
    assert run.assessment["display_lag_ms"] is not None
    # the debrief page: plain words, the replay, the record
    debrief = window.views["debrief"]
    assert isinstance(debrief, DebriefView) and debrief.debrief is not None
    window.pages.setCurrentWidget(debrief)
    texts = [label.text() for label in debrief.line_labels]
    assert texts[0].startswith("Score: ") and "You stayed out of the safety zone" in texts[2]
    assert "score" in debrief.line_labels[0].toolTip()
    debrief.scrub.setFocus()
    qtbot.keyClick(debrief.scrub, Qt.Key.Key_Home)
    assert debrief.cursor_label.text().startswith("at 0.00 s: drill 0.")
    qtbot.keyClick(debrief.scrub, Qt.Key.Key_End)
    assert "drill 10.80 mm deep" in debrief.cursor_label.text()
    db = tmp_path / "record.sqlite"
    qtbot.mouseClick(debrief.db_edit, Qt.MouseButton.LeftButton)
    qtbot.keyClicks(debrief.db_edit, str(db))
    qtbot.keyClicks(debrief.trainee_edit, "student-7")
    qtbot.mouseClick(debrief.compare_button, Qt.MouseButton.LeftButton)
    assert "no such trainee record" in debrief.record_message.text()
    qtbot.mouseClick(debrief.save_button, Qt.MouseButton.LeftButton)
    assert debrief.record_message.text().startswith("Saved: session ")
    qtbot.mouseClick(debrief.save_button, Qt.MouseButton.LeftButton)
    assert debrief.record_message.text().startswith("Already in the record")
    # the window's session is the one the exported folder gives ctdrill assess (same hash)
    panel.export(tmp_path / "export")
    assert (
        main(["assess", str(tmp_path / "export"), "--db", str(db), "--trainee", "student-7"]) == 0
    )
    with sqlite3.connect(db) as conn:
        rows = conn.execute("SELECT trainee, expert, score FROM sessions").fetchall()
    assert rows == [("student-7", 0, run.assessment["score"])]
    _expert_session(phantom_case, tmp_path, db)
    qtbot.mouseClick(debrief.compare_button, Qt.MouseButton.LeftButton)
    assert debrief.expert is not None and "dr-expert" in debrief.record_message.text()
    depth_ax = debrief.figure.axes[0]
    assert "expert" in [line.get_label() for line in depth_ax.lines]
    qtbot.wait(200)
    window.grab().save(str(tmp_path / "debrief.png"))
    assert (
        main(
            ["assess", "--db", str(db), "--trainee", "student-7", "--out", str(tmp_path / "curve")]
        )
        == 0
    )


@pytest.mark.timeout(240)
def test_exam_mode_lets_the_drill_into_the_canal_and_the_debrief_says_so(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    window.tabs.setCurrentWidget(panel)
    panel.duration_s = 60.0
    qtbot.mouseClick(panel.exam, Qt.MouseButton.LeftButton)
    assert panel.exam.isChecked()
    panel.hand.setFocus()
    qtbot.keyClick(panel.hand, Qt.Key.Key_PageDown)  # 12 -> 17 N
    qtbot.mouseClick(panel.connect_button, Qt.MouseButton.LeftButton)
    run = panel.run
    assert run is not None and run.exam is not None
    assert run.table.stop_depth_mm == pytest.approx(22.0, abs=1e-4)  # no wall at 10.8 mm
    assert panel.depth_gauge.stop_mm == pytest.approx(22.0, abs=1e-4)
    qtbot.waitUntil(
        lambda: panel.last is not None and panel.last.drill_mm > 13.5, timeout=SESSION_MS
    )
    panel.hand.setFocus()
    qtbot.keyClick(panel.hand, Qt.Key.Key_Space)  # let go, late
    _shots(window, tmp_path, "exam-in-the-canal")
    with qtbot.waitSignal(panel.finished, timeout=SESSION_MS):
        qtbot.keyClick(panel.hand, Qt.Key.Key_R)  # and pull out: the session ends
    a = run.assessment
    assert a is not None and a["breach"] is True and a["canal_entered"] is True
    assert a["overshoot_mm"] > 2.5 and a["score"] < 45.0 and a["time_in_margin_s"] > 0.0
    assert run.session is not None and run.session["final_master_mm"] <= 0.0
    debrief = window.views["debrief"]
    assert isinstance(debrief, DebriefView)
    window.pages.setCurrentWidget(debrief)
    assert "exam" in debrief.title.text()
    breach = [label for label in debrief.line_labels if "past the safe depth" in label.text()]
    assert breach and "entered the canal itself" in breach[0].text()
    assert "c62828" in breach[0].styleSheet()
    summary = run.summary()
    assert summary["exam"]["enabled"] is True and summary["assessment"] == a
    qtbot.wait(200)
    window.grab().save(str(tmp_path / "exam-debrief.png"))
