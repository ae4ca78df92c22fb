"""The window's rehearsal decisions, headless: what table a session uploads, when exam mode
can be switched (``app.gui.rehearsal_choice``, like the window's session runs, imports no Qt)."""

from __future__ import annotations

from ctdrill.app.gui.rehearsal_choice import SIMULATOR, exam_settable, session_exam
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.load import load_plan
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"


def test_the_exam_table_follows_the_device_and_the_toggle() -> None:
    volume, plan = load_series(DEMO / "ct"), load_plan(DEMO / "plan.json")
    path = plan_path(volume, plan.drilled(0), plan_calibration(plan))
    assert session_exam(volume, plan, path, SIMULATOR, exam=False) is None  # the margin's wall
    sim = session_exam(volume, plan, path, SIMULATOR, exam=True)
    robot = session_exam(volume, plan, path, "serial:/dev/ttyUSB9", exam=True)  # never opened
    assert sim is not None and robot is not None
    # the simulator's wall lies past the plan; the robot's at the canal's surface, shallower
    assert sim.table.stop_depth_mm > path.stop_depth_mm
    assert path.stop_depth_mm < robot.table.stop_depth_mm < sim.table.stop_depth_mm
    assert (sim.basis, robot.basis) == ("beyond_plan", "canal_surface")


def test_exam_mode_is_settable_unless_running_or_locked() -> None:
    assert exam_settable(running=False, locked=False)
    assert not exam_settable(running=True, locked=False)
    assert not exam_settable(running=False, locked=True)


def test_the_decisions_import_no_qt() -> None:
    import subprocess
    import sys

    code = (
        "import sys, ctdrill.app.gui.rehearsal, ctdrill.app.gui.rehearsal_choice\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('PySide6', 'vtk', 'pyvista')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
