"""Several trajectories in the document, which one is current, and undo/redo of plan edits."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.document import LOCKED_MESSAGE, Document
from ctdrill.app.gui.history import History, State
from ctdrill.app.gui.planning import edit_name, move_handle
from ctdrill.app.gui.results import path_view
from ctdrill.app.search.candidates import SearchSpace
from ctdrill.app.search.suggest import suggest
from ctdrill.engine.path import plan_path
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.model import load_calibration
from tests.app.gui.phantom import phantom_volume


def traj(name: str, x_mm: float = 0.0) -> Plan:
    return Plan(
        entry_lps=np.array([x_mm, 0.0, 12.0]), target_lps=np.array([x_mm, 0.0, 0.0]), name=name
    )


def log_of(doc: Document) -> list[tuple[str, object]]:
    log: list[tuple[str, object]] = []
    for name in ("plans_changed", "plan_changed", "path_changed", "edit_refused"):
        getattr(doc, name).connect(lambda value, n=name: log.append((n, value)))
    return log


def test_the_current_trajectory_is_the_plan_and_selecting_emits_both_signals(
    qtbot: QtBot,
) -> None:
    doc = Document()
    a, b, c = traj("a"), traj("b", 5.0), traj("c", 10.0)
    assert doc.plan is None and doc.plans == ()
    assert doc.set_plans((a, b, c), current=1)
    assert doc.plan is b and doc.current == 1
    assert not doc.can_undo  # a plan file opened: a new history
    log = log_of(doc)
    assert doc.select(2) and doc.plan is c
    assert log == [("plans_changed", (a, b, c)), ("plan_changed", c)]
    assert not doc.select(3) and not doc.select(-1) and doc.plan is c
    assert not doc.can_undo  # selecting is not an edit


def test_set_plan_replaces_the_current_one_only(qtbot: QtBot) -> None:
    doc = Document()
    a, b = traj("a"), traj("b", 5.0)
    doc.set_plans([a, b], current=1)
    moved = move_handle(b, "target", np.array([5.0, 0.0, 2.0]))
    assert doc.set_plan(moved)
    assert doc.plans == (a, moved) and doc.current == 1
    assert doc.history.undo_name == "move target"


def test_undo_and_redo_walk_every_edit_kind_back_and_forth(qtbot: QtBot) -> None:
    doc = Document()
    a, b = traj("a"), traj("b", 5.0)
    doc.set_plans([a])
    history: list[tuple[tuple[Plan, ...], int]] = [(doc.plans, doc.current)]
    names: list[str] = []

    def edit(ok: bool) -> None:
        assert ok
        history.append((doc.plans, doc.current))
        assert doc.history.undo_name is not None
        names.append(doc.history.undo_name)

    edit(doc.set_plan(move_handle(a, "entry", np.array([0.0, 1.0, 12.0]))))
    edit(doc.set_plan(replace(doc.plans[0], drill=DrillSpec(diameter_mm=3.5))))
    edit(doc.add_plan(b))
    edit(doc.set_plan(replace(b, name="36")))
    edit(doc.remove_plan(0))
    assert names == [
        "move entry",
        "change drill",
        "add trajectory 'b'",
        "rename trajectory",
        "remove trajectory 'a'",
    ]
    for k in range(len(history) - 1, 0, -1):
        assert doc.history.undo_name == names[k - 1]
        assert doc.undo()
        assert (doc.plans, doc.current) == history[k - 1]
    assert not doc.can_undo and not doc.undo()
    for k in range(1, len(history)):
        assert doc.history.redo_name == names[k - 1]
        assert doc.redo()
        assert (doc.plans, doc.current) == history[k]
    assert not doc.can_redo and not doc.redo()
    doc.undo()
    doc.set_plan(replace(doc.plan, margin_mm=3.0))  # type: ignore[arg-type]
    assert not doc.can_redo  # a new edit clears the redo side


def test_undo_of_an_edit_on_another_trajectory_selects_it(qtbot: QtBot) -> None:
    doc = Document()
    a, b = traj("a"), traj("b", 5.0)
    doc.set_plans([a, b])
    doc.set_plan(replace(a, feed_mm_s=0.8))
    doc.select(1)
    assert doc.undo()
    assert doc.current == 0 and doc.plan is a


def test_removing_keeps_the_current_trajectory_when_it_survives(qtbot: QtBot) -> None:
    doc = Document()
    a, b, c = traj("a"), traj("b", 5.0), traj("c", 10.0)
    doc.set_plans([a, b, c], current=2)
    assert doc.remove_plan(0) and doc.plan is c and doc.current == 1
    assert doc.remove_plan(1) and doc.plan is b and doc.current == 0
    assert doc.remove_plan(0) and doc.plan is None and doc.plans == ()
    assert not doc.remove_plan(0)
    assert doc.undo() and doc.plans == (b,)


def test_rehearsal_lock_refuses_every_edit_undo_and_selection(qtbot: QtBot) -> None:
    doc = Document()
    a, b = traj("a"), traj("b", 5.0)
    doc.set_plans([a, b])
    doc.set_plan(replace(a, margin_mm=2.5))
    edited = doc.plans
    doc.set_rehearsing(True)
    log = log_of(doc)
    assert not doc.undo()
    assert not doc.select(1)
    assert not doc.add_plan(traj("c"))
    assert not doc.remove_plan(1)
    assert not doc.set_plans([a])
    assert doc.plans is edited and doc.current == 0
    assert log == [("edit_refused", LOCKED_MESSAGE)] * 5
    doc.set_rehearsing(False)
    assert doc.undo() and doc.plans == (a, b)


def test_switching_back_shows_the_path_already_computed(qtbot: QtBot) -> None:
    doc = Document()
    vol = phantom_volume()
    cal = load_calibration("bone-illustrative")
    a, b = traj("a"), traj("b", 1.0)
    doc.volume = vol
    doc.set_plans([a, b])
    view_a = path_view(a, plan_path(vol, a, cal))
    doc.set_path(view_a)
    assert doc.path is view_a
    doc.select(1)
    assert doc.path is None  # b not computed yet
    log = log_of(doc)
    doc.select(0)
    assert doc.path is view_a
    assert log == [("plans_changed", (a, b)), ("plan_changed", a), ("path_changed", view_a)]
    assert doc.cached_path(b) is None
    doc.set_volume(vol, "again", None)  # a series (re)opened: computed paths forgotten
    assert doc.cached_path(a) is None


def test_undo_of_an_adopted_suggestion_restores_the_axis_and_the_suggestion(
    qtbot: QtBot,
) -> None:
    doc = Document()
    vol = phantom_volume()
    first = traj("a")
    doc.volume = vol
    doc.set_plans([first])
    s = suggest(vol, first, load_calibration("bone-illustrative"), SearchSpace(count=3))
    doc.request_suggestion(SearchSpace(count=3))
    doc.set_suggestion(first, s)
    assert doc.adopt_candidate(1)
    assert doc.history.undo_name == "adopt suggested axis 2"
    assert doc.undo()
    assert doc.plan is first and doc.suggestion is s and doc.adopted is None
    assert doc.redo()
    assert doc.adopted == 1 and doc.suggestion is s
    assert np.array_equal(doc.plan.entry_lps, s.candidates.entries_lps[1])  # type: ignore[union-attr]


def test_edit_names_follow_the_first_changed_field() -> None:
    a = traj("a")
    assert edit_name(None, a) == "place trajectory"
    assert edit_name(a, replace(a, target_lps=np.array([0.0, 0.0, 1.0]))) == "move target"
    both = replace(a, entry_lps=np.array([1.0, 0.0, 12.0]), target_lps=np.array([1.0, 0, 0]))
    assert edit_name(a, both) == "move trajectory"
    assert edit_name(a, replace(a, calibration="bone-illustrative")) == "change calibration"
    assert edit_name(a, replace(a)) == "edit trajectory"


def test_history_keeps_at_most_its_step_count() -> None:
    h = History(max_steps=3)
    states = [State((traj(str(k)),), 0) for k in range(6)]
    for k in range(5):
        h.push(f"e{k}", states[k])
    now = states[5]
    undone = []
    while (s := h.undo(now)) is not None:
        undone.append(s)
        now = s
    assert undone == [states[4], states[3], states[2]]


def test_a_landmark_edit_on_one_trajectory_is_the_plans(qtbot: QtBot) -> None:
    from ctdrill.app.gui.canal_edit import trace

    doc = Document()
    a, b = traj("a"), traj("b", 5.0)
    doc.set_plans([a, b])
    edited, _, _ = trace(a, np.array([1.0, 2.0, -3.0]), name="canal")
    assert doc.set_plan(edited)
    assert doc.plans[0] is edited
    assert doc.plans[1].landmarks is edited.landmarks and doc.plans[1].name == "b"
    assert np.array_equal(doc.plans[1].entry_lps, b.entry_lps)
    assert doc.history.undo_name == "edit landmarks"
    assert doc.undo() and doc.plans == (a, b)


def test_a_new_trajectory_goes_along_the_arch_or_to_the_left() -> None:
    from ctdrill.app.gui.planning import new_trajectory

    a = traj("implant 1")
    b, where = new_trajectory([a], 0)
    assert np.array_equal(b.entry_lps - a.entry_lps, [8.0, 0.0, 0.0])
    assert b.name == "implant 2" and "patient's left" in where
    # A straight arch along +y from y = -30 to y = +10: the target at y = 0 is 30 mm from the
    # first end and 10 mm from the last, so the copy goes 8 mm toward the first (-y).
    arch = np.array([[0.0, -30.0, 0.0], [0.0, 10.0, 0.0]])
    on_arch = replace(a, arch_lps=arch)
    c, where = new_trajectory([on_arch], 0)
    np.testing.assert_allclose(c.target_lps - on_arch.target_lps, [0.0, -8.0, 0.0], atol=1e-12)
    assert "8.0 mm along the arch" in where
    near_end = replace(on_arch, entry_lps=[0.0, 6.0, 12.0], target_lps=[0.0, 6.0, 0.0])
    d, where = new_trajectory([near_end], 0)  # only 6 mm... no: 36 mm to the first end
    np.testing.assert_allclose(d.target_lps[:2], [0.0, -2.0], atol=1e-12)
    beyond = replace(on_arch, entry_lps=[0.0, 20.0, 12.0], target_lps=[0.0, 20.0, 0.0])
    e, where = new_trajectory([beyond], 0)  # beside no point of the arch: the plain shift
    assert np.array_equal(e.target_lps - beyond.target_lps, [8.0, 0.0, 0.0])
    assert "beyond the arch's ends" in where


def test_the_arch_is_set_on_every_trajectory_refused_when_invalid_and_undone(
    qtbot: QtBot,
) -> None:
    doc = Document()
    arch = np.array([[-20.0, 0.0, 0.0], [0.0, -10.0, 0.0], [20.0, 0.0, 0.0]])
    doc.set_arch(arch)  # before any trajectory: kept for the first one
    assert np.array_equal(doc.arch_lps, arch) and not doc.can_undo  # type: ignore[arg-type]
    first = traj("a")
    assert doc.set_plan(first)
    assert doc.plan is not None and np.array_equal(doc.plan.arch_lps, arch)  # type: ignore[arg-type]
    assert doc.add_plan(traj("b", 5.0))
    moved = arch + np.array([0.0, 1.0, 0.0])
    assert doc.set_arch(moved) and doc.history.undo_name == "edit arch"
    assert all(np.array_equal(p.arch_lps, moved) for p in doc.plans)  # type: ignore[arg-type]
    log = log_of(doc)
    assert not doc.set_arch(np.array([[0.0, 0.0, 0.0]]))  # one point is no arch
    assert log[0][0] == "edit_refused" and "arch" in str(log[0][1]) and len(log) == 1
    assert doc.set_arch(None) and doc.history.undo_name == "remove arch"
    assert all(p.arch_lps is None for p in doc.plans)
    assert doc.undo() and doc.undo()
    assert all(np.array_equal(p.arch_lps, arch) for p in doc.plans)  # type: ignore[arg-type]
    assert doc.history.undo_name == "add trajectory 'b'"
