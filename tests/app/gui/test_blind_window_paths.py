"""The window's other ways to a blind trial's CT (docs/exercises.md, "Blind trials and the other
commands"): opening a trial's CT outside its blind trial is refused, and a plan opened on a
trial's CT keeps the window blind."""

from __future__ import annotations

from pathlib import Path

import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.exercise.bone_quality import write_bone_quality
from ctdrill.app.gui.main_window import MainWindow
from tests.app.gui.helpers import LOAD_TIMEOUT_MS

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

DEMO_PLAN = Path(__file__).resolve().parents[3] / "assets" / "demo" / "plan.json"


@pytest.mark.timeout(120)
def test_a_trials_ct_opens_only_in_its_blind_trial(
    qtbot: QtBot, window: MainWindow, tmp_path: Path
) -> None:
    write_bone_quality(tmp_path / "trials", trials=2, seed=4, spacing_mm=1.0)
    one, two = tmp_path / "trials" / "trial-01", tmp_path / "trials" / "trial-02"
    window.show()
    qtbot.waitExposed(window, timeout=LOAD_TIMEOUT_MS)
    with qtbot.waitSignal(window.load_failed, timeout=LOAD_TIMEOUT_MS) as refused:
        window.open_folder(one / "ct")  # no trial open: the views would show the bone
    assert "blind trial" in str(refused.args[0]) and window.doc.volume is None
    window.open_plan(one / "plan.json")
    assert window.blind_trial is not None and window.blind_trial.trial == "trial-01"
    with qtbot.waitSignal(window.load_failed, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(two / "ct")  # another trial's CT
    with qtbot.waitSignal(window.volume_loaded, timeout=LOAD_TIMEOUT_MS):
        window.open_folder(one / "ct")  # its own: blind
    assert window.blind_trial is not None and not window.pages.isVisible()
    window.open_plan(DEMO_PLAN)  # another plan on the trial's CT: still blind
    assert window.blind_trial is not None and window.blind_trial.trial == "trial-01"
    assert not window.pages.isVisible()
