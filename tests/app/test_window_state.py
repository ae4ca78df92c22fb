"""The window's state is a plain evented object: imported with Qt blocked, a plan edit, a
draft, a rehearsal and its debrief announce themselves as typed events."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from ctdrill.app.gui.state.events import Event, events_of

SCRIPT = textwrap.dedent(
    """
    import sys
    for name in ("PySide6", "PySide6.QtCore", "PySide6.QtWidgets", "pyvistaqt"):
        sys.modules[name] = None  # importing any of them now raises ImportError
    import numpy as np
    from ctdrill.app.gui.state.window import LOCKED_MESSAGE, WindowState
    from ctdrill.imaging.plan.types import Plan

    state = WindowState()
    log = []
    for name in ("plans_changed", "plan_changed", "history_changed", "rehearsal_changed",
                 "edit_refused", "debrief_changed", "live_depth_changed"):
        getattr(state, name).connect(lambda *v, n=name: log.append((n, v)))

    state.set_draft_point("entry", np.array([0.0, 0.0, 12.0]))
    assert set(state.draft) == {"entry"} and log == [("plan_changed", (None,))]
    del log[:]
    plan = Plan(entry_lps=np.array([0.0, 0.0, 12.0]), target_lps=np.array([0.0, 0.0, 0.0]))
    assert state.set_plan(plan)
    assert state.plans == (plan,) and state.draft == {} and state.can_undo
    assert [n for n, _ in log] == ["plans_changed", "plan_changed", "history_changed"]
    assert log[1] == ("plan_changed", (plan,))
    del log[:]
    state.set_rehearsing(True)
    state.set_live_depth(3)
    assert not state.set_plan(None)  # locked while the rehearsal runs
    assert log == [("rehearsal_changed", (True,)), ("live_depth_changed", (3,)),
                   ("edit_refused", (LOCKED_MESSAGE,))]
    del log[:]
    state.set_rehearsing(False)
    state.set_debrief("debrief")
    assert state.live_depth_mm is None and state.debrief == "debrief"
    assert log == [("rehearsal_changed", (False,)), ("debrief_changed", ("debrief",))]
    assert state.undo() and state.plans == ()
    assert not any(m.startswith(("PySide6", "shiboken6", "pyvistaqt", "vtkmodules.qt"))
                   and sys.modules[m] is not None for m in sys.modules)
    print("ok")
    """
)


def test_the_window_state_runs_without_qt() -> None:
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


class _Thing:
    changed = Event(str, float)
    other = Event()


def test_events_are_typed_per_instance_and_ordered() -> None:
    a, b = _Thing(), _Thing()
    got: list[tuple[object, ...]] = []
    a.changed.connect(lambda *v: got.append(("first", *v)))
    a.changed.connect(lambda *v: got.append(("second", *v)))
    a.changed.emit("x", 2)
    b.changed.emit("y", 1.0)  # b has no callbacks of a's
    assert got == [("first", "x", 2), ("second", "x", 2)]
    with pytest.raises(TypeError, match="changed takes 2 values"):
        a.changed.emit("x")
    with pytest.raises(TypeError, match="is not a float"):
        a.changed.emit("x", "2")
    a.changed.disconnect()
    a.changed.emit("z", 0.0)
    assert len(got) == 2
    assert events_of(_Thing) == ("changed", "other")
