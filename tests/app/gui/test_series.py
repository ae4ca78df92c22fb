"""Real series in the window: the series picker, loader warnings, rehearsal blocked with why."""

from __future__ import annotations

from pathlib import Path

import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui import compute
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.scene import CLEARANCE_COLOURS
from tests.app.gui.helpers import LOAD_TIMEOUT_MS

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

DEMO_PLAN = Path(__file__).resolve().parents[3] / "assets" / "demo" / "plan.json"
MIXED = "dcmqa_ct_Philips_phantom_gantrytilt_mixedfolder"
SMALLER_UID = "1.3.46.670589.33.1.7303547162003802183.31761132431540865648"  # the 54-slice one


def test_several_series_ask_and_load_the_chosen_one(
    qtbot: QtBot, window: MainWindow, shared_data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    offered: list[compute.SeriesChoice] = []

    def choose(choice: compute.SeriesChoice) -> str:
        offered.append(choice)
        return SMALLER_UID

    monkeypatch.setattr(window, "choose_series", choose)
    with qtbot.waitSignal(window.volume_loaded, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(shared_data / MIXED)
    assert [s.n_slices for s in offered[0].series] == [58, 54]
    assert window.volume is not None
    assert window.volume.info.series_uid == SMALLER_UID
    assert window.volume.hu.shape[0] == 54
    codes = [
        window.warnings_list.item(i).text().split(":")[0]
        for i in range(window.warnings_list.count())
    ]
    assert "gantry_tilt" in codes


def test_cancelling_the_series_choice_loads_nothing(
    qtbot: QtBot, window: MainWindow, shared_data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(window, "choose_series", lambda choice: None)
    window.open_folder(shared_data / MIXED)
    qtbot.waitUntil(
        lambda: window.statusBar().currentMessage() == "loading cancelled", timeout=LOAD_TIMEOUT_MS
    )
    assert window.volume is None


def test_a_single_slice_blocks_rehearsal_and_says_why(
    qtbot: QtBot, window: MainWindow, shared_data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    single = "2.16.840.1.113662.2.12.0.3057.1241703565.43"  # the RT planning CT slice
    monkeypatch.setattr(window, "choose_series", lambda choice: single)
    assert window.open_plan(DEMO_PLAN)
    with qtbot.waitSignal(window.path_failed, timeout=LOAD_TIMEOUT_MS) as failed:
        window.open_folder(shared_data / "single_slice_ct")
    assert "single slice" in failed.args[0]
    qtbot.waitUntil(
        lambda: "margin:left mandibular canal" in window.view3d.actors, timeout=LOAD_TIMEOUT_MS
    )
    # The plan and the anatomy are still drawn; the plots say why there is no profile.
    assert "drill" in window.view3d.actors and "trajectory" in window.view3d.actors
    assert "no force profile" in window.plot_canvas.message
    assert "Rehearsal disabled" in window.block_label.text()
    assert not window.rehearsal.connect_button.isEnabled()
    assert "single slice" in window.rehearsal.message.text()
    # Unknown is never shown as safe: the canal's margin is grey, its clearance "unknown".
    colour = window.view3d.actors["margin:left mandibular canal"].GetProperty().GetColor()
    assert colour == pytest.approx(CLEARANCE_COLOURS["unknown"], abs=1 / 255)
    assert window.plan_panel.table.item(0, 3).text() == "unknown"
    banner = window.views["banner"]
    assert banner.isVisible() and "unknown" in banner.text() and "single slice" in banner.text()


def test_the_series_tab_shows_every_warning_whole(
    qtbot: QtBot, window: MainWindow, shared_data: Path, tmp_path: Path
) -> None:
    from ctdrill.imaging import LoadWarning

    window.resize(1280, 800)
    with qtbot.waitSignal(window.volume_loaded, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(shared_data / "dcmqa_ct_GE_head_gantrytilt_varspacing")
    panel = window.series_panel
    window.tabs.setCurrentWidget(panel)
    # the real loader warnings, plus one holding a path far longer than a line (no spaces)
    long_path = "/".join(["a_very_long_folder_name_without_spaces"] * 12) + "/slice.dcm"
    assert window.volume is not None
    warnings = (*window.volume.warnings, LoadWarning("files_skipped", f"skipped {long_path}"))
    panel.set_load_warnings(warnings)
    box = panel.warnings_list
    for width in (900, 340):  # wide, then as narrow as the tab gets
        window.tabs.setFixedWidth(width)

        def laid_out(width: int = width) -> bool:
            """The list has taken the tab's new width and wrapped its items to it."""
            view_w = box.viewport().width()
            return view_w <= width and all(
                box.visualItemRect(box.item(row)).width() <= view_w
                and box.visualItemRect(box.item(row)).height() >= box.text_height(row)
                for row in range(box.count())
            )

        qtbot.waitUntil(laid_out, timeout=LOAD_TIMEOUT_MS)  # the layout runs on the event loop
        assert box.count() == len(warnings)
        view_w = box.viewport().width()
        for row in range(box.count()):
            text = box.item(row).text()
            assert text == f"{warnings[row].code}: {warnings[row].message}"  # the whole text
            rect = box.visualItemRect(box.item(row))
            assert rect.width() <= view_w  # nothing runs off the right edge
            assert rect.height() >= box.text_height(row)  # every wrapped line shown
        # the long path needs several lines at this width: it wraps inside the word
        assert box.text_height(box.count() - 1) > 3 * box.fontMetrics().height()
    assert box.horizontalScrollBar().maximum() == 0
    window.grab().save(str(tmp_path / "series_tab.png"))
