"""The window's document: one owner of the volume, the plan, the path result and the
rehearsal state; its changes are signals, and the plan is locked while a rehearsal runs."""

from __future__ import annotations

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.document import LOCKED_MESSAGE, Document
from ctdrill.app.gui.results import path_view
from ctdrill.app.gui.series_panel import unique_warnings
from ctdrill.app.gui.views import VIEWS
from ctdrill.engine.path import plan_path
from ctdrill.imaging import LoadWarning
from ctdrill.imaging.plan.types import Plan
from ctdrill.model import load_calibration
from tests.app.gui.phantom import phantom_volume


def plan(z_target: float = 0.0) -> Plan:
    return Plan(entry_lps=np.array([0.0, 0.0, 12.0]), target_lps=np.array([0.0, 0.0, z_target]))


def record(doc: Document) -> list[tuple[str, object]]:
    log: list[tuple[str, object]] = []
    for name in ("plan_changed", "path_changed", "rehearsal_changed", "edit_refused"):
        getattr(doc, name).connect(lambda value, n=name: log.append((n, value)))
    return log


def test_a_plan_change_resets_the_path_and_a_stale_result_is_dropped(qtbot: QtBot) -> None:
    doc = Document()
    log = record(doc)
    first = plan()
    assert doc.set_plan(first)
    view = path_view(
        first, plan_path(phantom_volume(), first, load_calibration("bone-illustrative"))
    )
    second = plan(1.0)
    doc.set_plan(second)
    doc.set_path(view)  # computed for the first plan: dropped
    assert doc.path is None
    doc.set_path_failed(first, "stale")  # idem
    assert doc.path_error == ""
    doc.set_path_failed(second, "no data there")
    assert doc.path is None and doc.path_error == "no data there"
    assert log == [
        ("plan_changed", first),
        ("plan_changed", second),
        ("path_changed", None),
    ]


def test_the_plan_is_locked_while_a_rehearsal_runs(qtbot: QtBot) -> None:
    doc = Document()
    first = plan()
    doc.set_plan(first)
    doc.set_rehearsing(True)
    log = record(doc)
    assert not doc.set_plan(plan(2.0))
    doc.set_draft_point("target", np.zeros(3))
    assert doc.plan is first and doc.draft == {}
    assert log == [("edit_refused", LOCKED_MESSAGE), ("edit_refused", LOCKED_MESSAGE)]
    doc.set_rehearsing(False)
    assert doc.set_plan(plan(2.0)) and doc.plan is not first


def test_views_register_in_one_place_with_unique_keys() -> None:
    keys = [spec.key for spec in VIEWS]
    assert len(keys) == len(set(keys))
    expected = {"3d", "slices", "panorama", "plots", "plan", "suggest", "rehearsal", "series"}
    expected |= {"debrief", "teleop"}
    assert expected | {"banner"} == set(keys)
    assert {spec.area for spec in VIEWS} <= {"banner", "main", "page", "bottom", "tab"}


def test_each_warning_is_listed_once() -> None:
    a = LoadWarning("nonuniform_spacing", "3 irregular slice steps")
    b = LoadWarning("padding", "pixels outside the field")
    assert unique_warnings([a, b, a, b]) == [a, b]
    assert unique_warnings([a, b, a], already=[a]) == [b]
    assert unique_warnings([LoadWarning("slice_gap", "one"), LoadWarning("slice_gap", "two")]) == [
        LoadWarning("slice_gap", "one"),
        LoadWarning("slice_gap", "two"),
    ]


@pytest.mark.parametrize("running", [True, False])
def test_rehearsal_state_is_signalled_once_per_change(qtbot: QtBot, running: bool) -> None:
    doc = Document()
    log = record(doc)
    doc.set_rehearsing(running)
    doc.set_rehearsing(running)
    assert log == ([("rehearsal_changed", True)] if running else [])
