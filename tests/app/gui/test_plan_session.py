"""A planning session in the window: several trajectories, the current one's path, undo/redo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication, QLineEdit
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.imaging.phantom.io import PhantomCase
from ctdrill.imaging.plan.protocol import protocol_drills
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

DEMO_PLAN = Path(__file__).resolve().parents[3] / "assets" / "demo" / "plan.json"

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def wait_path(qtbot: QtBot, window: MainWindow) -> None:
    qtbot.waitUntil(
        lambda: window.view is not None and window.view.plan is window.plan,
        timeout=LOAD_TIMEOUT_MS,
    )


def test_add_select_rename_remove_trajectories_and_undo_each(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    open_case(qtbot, window, phantom_case)
    doc, tl = window.doc, window.plan_panel.trajectories
    first = window.plan
    assert first is not None and tl.list.count() == 1
    first_view = window.view
    assert window.undo_action.text() == "Undo" and not window.undo_action.isEnabled()

    tl.add.click()  # a copy 8 mm along the phantom's arch (a polyline on a 32 mm circle)
    assert len(doc.plans) == 2 and doc.current == 1 and tl.list.currentRow() == 1
    second = doc.plans[1]
    shift = second.entry_lps - first.entry_lps
    assert np.array_equal(second.target_lps - first.target_lps, shift) and shift[2] == 0.0
    chord = 2 * 32.0 * np.sin(4.0 / 32.0)  # an 8 mm arc's chord on the circle: 7.979 mm
    assert chord - 0.02 < np.linalg.norm(shift) <= 8.0
    assert second.name == "implant 1" and second.drill == first.drill
    assert window.undo_action.text() == "Undo add trajectory 'implant 1'"
    wait_path(qtbot, window)  # the new current trajectory's path is computed
    second_view = window.view
    assert second_view is not None and second_view is not first_view

    tl.list.setCurrentRow(0)  # selecting shows the path already computed, at once
    assert window.plan is first and window.view is first_view
    assert window.plan_panel.point_boxes["entry"][0].value() == pytest.approx(first.entry_lps[0])
    tl.list.setCurrentRow(1)
    assert window.view is second_view

    tl.rename.click()  # the editor opens on the bare name; typing a new one renames
    editors = [e for e in tl.list.findChildren(QLineEdit) if e.isVisible()]
    assert len(editors) == 1 and editors[0].text() == second.name
    editor = editors[0]
    editor.selectAll()
    qtbot.keyClicks(editor, "35")
    qtbot.keyClick(editor, Qt.Key.Key_Return)
    qtbot.waitUntil(
        lambda: window.plan is not None and window.plan.name == "35", timeout=LOAD_TIMEOUT_MS
    )
    assert tl.list.item(1).text().startswith("2. 35  (")
    rect = tl.list.visualItemRect(tl.list.item(1))  # a double-click opens the same editor
    qtbot.mouseClick(tl.list.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
    qtbot.mouseDClick(tl.list.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
    editors = [e for e in tl.list.findChildren(QLineEdit) if e.isVisible()]
    assert len(editors) == 1 and editors[0].text() == "35"
    qtbot.keyClick(editors[0], Qt.Key.Key_Escape)  # cancelled: the row's label comes back
    qtbot.waitUntil(lambda: tl.list.item(1).text().startswith("2. 35  ("), timeout=LOAD_TIMEOUT_MS)
    assert tl.rename_current("36")
    assert window.plan is not None and window.plan.name == "36"
    assert tl.list.item(1).text().startswith("2. 36  (")
    assert not tl.rename_current("") and not tl.rename_current(first.name)  # refused
    assert window.undo_action.text() == "Undo rename trajectory"

    moved = window.plan.target_lps + np.array([0.0, 0.0, 1.0])
    window.slice_canvases["coronal"].point_moved.emit("target", moved)
    assert window.undo_action.text() == "Undo move target"
    window.plan_panel.diameter.setValue(3.0)
    assert window.undo_action.text() == "Undo change drill"

    tl.remove.click()
    assert len(doc.plans) == 1 and window.plan is first
    assert window.undo_action.text() == "Undo remove trajectory '36'"

    expected = [
        ("remove trajectory '36'", 2),
        ("change drill", 2),
        ("move target", 2),
        ("rename trajectory", 2),
        ("rename trajectory", 2),
        ("add trajectory 'implant 1'", 1),
    ]
    for name, count in expected:  # Edit > Undo, as the menu item does it
        assert window.undo_action.text() == f"Undo {name}"
        window.undo_action.trigger()
        assert len(doc.plans) == count and tl.list.count() == count
    assert doc.plans == (first,) and not window.undo_action.isEnabled()
    assert window.redo_action.text() == "Redo add trajectory 'implant 1'"
    for _ in expected:
        window.redo_action.trigger()
    assert [p.name for p in doc.plans] == [first.name]
    assert window.plan is first
    window.activateWindow()
    qtbot.waitUntil(lambda: QApplication.activeWindow() is window, timeout=LOAD_TIMEOUT_MS)
    qtbot.keyClick(
        window.plan_panel.trajectories.list, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier
    )
    assert len(doc.plans) == 2  # Ctrl+Z undid the removal


def test_pick_an_implant_from_the_library_and_undo_it(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    picker = window.plan_panel.implant
    library = picker.library
    assert len(library) >= 2 and picker.count() >= len(library) + 1
    before = window.plan
    assert before is not None
    target = next(s for s in library if s != before.implant)
    assert picker.pick(target.name)
    assert window.plan is not None and window.plan.implant == target
    assert window.undo_action.text() == f"Undo pick implant {target.name!r}"
    # picking applies the implant's protocol in the same edit (one undo step)
    got = [(d.diameter_mm, d.tip_length_mm) for d in window.plan.drills]
    assert got == [(d.diameter_mm, d.tip_length_mm) for d in protocol_drills(target)[0]]
    assert picker.pick(None)
    assert window.plan is not None and window.plan.implant is None
    assert picker.currentText() == "(no implant)"
    assert window.undo_action.text() == "Undo remove implant"
    window.undo_action.trigger()
    assert window.plan is not None and window.plan.implant == target
    assert picker.spec == target  # the picker shows the undone state
    window.undo_action.trigger()
    assert window.plan is before and picker.spec == before.implant


def test_save_writes_every_trajectory_and_reopening_gives_them_back(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    from ctdrill.imaging.plan.load import load_plan_set

    open_case(qtbot, window, phantom_case)
    window.plan_panel.trajectories.add.click()
    window.plan_panel.trajectories.add.click()
    saved = window.doc.plans
    for name in ("all.json", "all.mrk.json"):
        window.save_plan(tmp_path / name)
        back = load_plan_set([tmp_path / name])
        assert [p.name for p in back] == [p.name for p in saved]
        for a, b in zip(back, saved, strict=True):
            np.testing.assert_allclose(a.entry_lps, b.entry_lps, atol=1e-9)
            np.testing.assert_allclose(a.target_lps, b.target_lps, atol=1e-9)
            assert a.drill == b.drill and a.implant == b.implant
    assert window.open_plan(tmp_path / "all.json")
    assert len(window.doc.plans) == 3 and window.doc.current == 0
    assert not window.undo_action.isEnabled()  # a plan file opened: a new history


def test_gui_command_loads_every_trajectory_of_repeated_plan_options(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import argparse
    from dataclasses import replace

    from ctdrill.app.commands import gui as gui_command
    from ctdrill.app.gui import app as gui_app
    from ctdrill.imaging.plan.implants import load_implant_library
    from ctdrill.imaging.plan.load import load_plan_set
    from ctdrill.imaging.plan.write import write_plans

    demo = load_plan_set([DEMO_PLAN])[0]
    write_plans([replace(demo, name="a"), replace(demo, name="b")], tmp_path / "ab.json")
    seen: dict[str, object] = {}
    monkeypatch.setattr(gui_app, "run_gui", lambda **kw: seen.update(kw) or 0)
    parser = argparse.ArgumentParser()
    gui_command.register(parser.add_subparsers())
    mine = tmp_path / "mine.json"
    mine.write_text(
        '{"format": "ctdrill-implants/1", "implants": [{"name": "mine 3.3 x 9", '
        '"diameter_mm": 3.3, "length_mm": 9.0, "apex_diameter_mm": 2.5, "apex": "flat"}]}'
    )
    ab = str(tmp_path / "ab.json")
    args = parser.parse_args(
        ["gui", "--plan", ab, "--plan", str(DEMO_PLAN), "--implants", str(mine)]
    )
    assert gui_command.run(args) == 0
    plans = seen["plans"]
    assert isinstance(plans, tuple) and [p.name for p in plans] == ["a", "b", "plan"]
    library = seen["implants"]
    assert isinstance(library, tuple) and library[-1].name == "mine 3.3 x 9"
    assert len(library) == len(load_implant_library()) + 1  # the generic sizes, extended


def test_an_implant_library_that_cannot_be_read_is_exit_2_before_any_window(
    tmp_path: Path,
) -> None:
    from tests.app.gui.test_command import one_error_line, run_gui

    bad = tmp_path / "implants.json"
    bad.write_text('{"format": "ctdrill-implants/1", "implants": [{"name": "x"}]}')
    err = one_error_line(run_gui(["--plan", str(DEMO_PLAN), "--implants", str(bad)], {}))
    assert "implants.json" in err and "diameter_mm" in err


def test_a_rehearsal_locks_the_trajectory_list_the_implant_and_undo(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    tl, doc = window.plan_panel.trajectories, window.doc
    tl.add.click()
    assert window.undo_action.isEnabled()
    doc.set_rehearsing(True)  # as the rehearsal panel does when the device is armed
    assert not window.undo_action.isEnabled() and not window.redo_action.isEnabled()
    assert not tl.add.isEnabled() and not tl.list.isEnabled()
    assert not window.plan_panel.body.isEnabled()  # the implant picker is in the locked body
    plans = doc.plans
    window.undo_action.trigger()  # a disabled action does nothing...
    assert not doc.undo()  # ...and the document refuses it anyway
    assert doc.plans is plans and doc.current == 1
    assert window.statusBar().currentMessage().startswith("the plan is locked")
    doc.set_rehearsing(False)
    assert window.undo_action.isEnabled() and tl.add.isEnabled()
    window.undo_action.trigger()
    assert len(doc.plans) == 1
