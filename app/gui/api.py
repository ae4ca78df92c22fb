"""Open the window from Python, ready to be driven (``ctdrill.api.open_window``).

An outside script (a test under Xvfb, a notebook) opens the window on a series and plans and
drives it with real Qt events: the views are found by their Qt object names (``view:axial``,
``view:coronal``, ``view:sagittal``, ``view:drill``, ``view:panorama``,
``view:cross_section``, ``plot:force``), each view maps widget pixels to LPS and back
(``pixel_to_lps(x, y)``, ``lps_to_pixel(lps)``), and the force plot's ``stopDepthMm``
property holds the stop depth it has drawn (docs/gui.md).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from PySide6.QtCore import QSettings

    from ctdrill.app.gui.main_window import MainWindow
    from ctdrill.imaging.plan.implants import ImplantSpec
    from ctdrill.imaging.plan.types import Plan

#: Longest wait for the series to load and its first path to be computed, ms.
OPEN_TIMEOUT_MS = 120_000

StrPath = str | os.PathLike[str]


def open_window(
    dicom: StrPath,
    plans: Sequence[StrPath | Plan] = (),
    implants: StrPath | Sequence[ImplantSpec] | None = None,
    *,
    settings: QSettings | None = None,
) -> MainWindow:
    """The shown main window with the series ``dicom`` loaded and its first computation
    finished (the current trajectory's path planned and drawn, or refused with a message),
    every view drawn and the compiled kernels loaded (numba loads after the first draw).

    Parameters
    ----------
    dicom : a DICOM series folder.
    plans : plan files (ctdrill-plan/1, Slicer markups, folders: merged as ``--plan`` does)
        or :class:`~ctdrill.imaging.plan.types.Plan` values; every trajectory is shown, the
        first current.
    implants : the implant library the window offers: a ``ctdrill-implants/1`` file or
        implant specs (None: the shipped library).
    settings : where the window keeps its settings (recent folders); None: the user's.

    Raises
    ------
    ValueError
        A plan, library or series that cannot be read (the input errors' message).
    TimeoutError
        The series did not load, or its path was not computed, within
        :data:`OPEN_TIMEOUT_MS`.
    """
    from ctdrill.app.gui.preload import import_window

    import_window()  # the Qt-free modules first (PySide6's import hook), the collector paused
    from PySide6.QtCore import QDeadlineTimer, QEventLoop, QTimer

    from ctdrill import jit
    from ctdrill.app.gui.app import make_window
    from ctdrill.imaging.plan.implants import load_implant_library
    from ctdrill.imaging.plan.load import load_plan_set
    from ctdrill.imaging.plan.types import Plan

    given = [p for p in plans if isinstance(p, Plan)]
    files = [p for p in plans if not isinstance(p, Plan)]
    trajectories = (*given, *(load_plan_set(files) if files else ()))
    library = (
        load_implant_library(implants) if isinstance(implants, str | os.PathLike) else implants
    )
    window = make_window(settings)
    window.unattended = True  # no modal dialog blocks the script; bugs are kept
    window.ask_series = False
    if library is not None:
        window.plan_panel.implant.set_library(tuple(library))
    if trajectories:
        window.use_plans(trajectories, trajectories[0].source)
    loop = QEventLoop()
    state = {"done": False, "error": ""}

    def finish(error: str = "") -> None:
        state["done"], state["error"] = True, error
        loop.quit()

    waits = [window.path_updated, window.path_failed] if trajectories else [window.slices_updated]
    for signal in waits:
        signal.connect(lambda *_a: finish())
    window.load_failed.connect(lambda message: finish(message or "the series did not load"))
    QTimer.singleShot(OPEN_TIMEOUT_MS, loop.quit)
    window.open_folder(dicom)
    if not state["done"]:
        loop.exec()
    if window.load_error is not None:
        window.close()
        raise window.load_error
    if state["error"]:
        window.close()
        raise ValueError(f"{dicom}: {state['error']}")
    if not state["done"]:
        window.close()
        raise TimeoutError(f"{dicom}: not loaded and computed within {OPEN_TIMEOUT_MS} ms")
    view3d = window.view3d
    deadline = QDeadlineTimer(OPEN_TIMEOUT_MS)
    # every view drawn (the 3D view's bone surface is contoured after the slices and the
    # path; its frames come from its render thread), then the compiled kernels loaded (in the
    # background once the views are drawn, app/gui/first_draw.py): the window is ready to be
    # driven, a drag computed by the kernels from its first move
    while (
        window.ui_steps.pending
        or view3d.busy
        or not view3d.surface_is_shown()
        or not window.first_draw.done
        or jit.deferred()
    ) and not deadline.hasExpired():
        loop.processEvents(QEventLoop.ProcessEventsFlag.WaitForMoreEvents, 50)
    return window
