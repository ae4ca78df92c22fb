"""The window's rehearsal choices, headless (no Qt): the devices offered, the device a choice
names, what table a session uploads (exam mode or the margin's wall) and when exam mode can be
switched. :class:`~ctdrill.app.gui.rehearsal_panel.RehearsalPanel` asks these."""

from __future__ import annotations

from serial.tools import list_ports

from ctdrill.app.trainee.exam import ExamSetup, exam_at_surface, exam_setup
from ctdrill.engine.path import PathResult
from ctdrill.haptics.spec import DeviceSpec
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume

#: The device-choice label of the simulator.
SIMULATOR = "simulator"


def device_choices() -> list[str]:
    """The simulator, then every serial port present (``serial:<device>``)."""
    ports = sorted(p.device for p in list_ports.comports())
    return [SIMULATOR, *(f"serial:{p}" for p in ports)]


def device_of(choice: str, *, realtime: bool) -> DeviceSpec:
    """The device a choice of :func:`device_choices` names (``realtime``: the simulator
    kept to the wall clock)."""
    return DeviceSpec.simulator(paced=realtime) if choice == SIMULATOR else DeviceSpec.parse(choice)


def session_exam(
    volume: CTVolume, plan: Plan, result: PathResult, choice: str, *, exam: bool
) -> ExamSetup | None:
    """What a session on the device ``choice`` uploads when exam mode is ``exam``: the exam's
    table (on the robot its wall at the nearest landmark's surface,
    :func:`~ctdrill.app.trainee.exam.exam_at_surface`), or None for the margin's wall."""
    if not exam:
        return None
    spec = device_of(choice, realtime=False)
    return exam_setup(volume, plan, result, at_surface=exam_at_surface(spec))


def exam_settable(*, running: bool, locked: bool) -> bool:
    """Exam mode can be switched unless a session runs or the aid level locks it."""
    return not running and not locked
