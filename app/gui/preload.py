"""Import the window's Qt-free modules before Qt (:func:`before_qt`), for a faster start.

Once PySide6 is imported, its feature hook (``shibokensupport.feature``) reads the source of
every module imported after it, to see whether the module uses PySide6: about 1200 modules
for the window, 0.2-0.3 s of CPU at start-up. The modules imported here (NumPy, matplotlib's
figure, pyvista and ctdrill's own Qt-free modules of the window) are imported before
it, so the hook never reads them. This module imports no Qt (a test checks). Not numba: the
window loads it after its first series is drawn (:mod:`ctdrill.app.gui.first_draw`); nor
SciPy's ``ndimage``, which the window does not use (the samplers give ``map_coordinates``'
bits without it); nor pydicom, which an uncompressed series does not need (the fast header
and pixel readers).
"""

from __future__ import annotations

import gc
import importlib
import sys

#: The Qt-free modules the window imports, roots first (each pulls its own imports in).
QT_FREE = (
    "numpy",
    "matplotlib.figure",
    "matplotlib.backends.backend_agg",
    "pyvista",
    "ctdrill.app.gui.compute",
    "ctdrill.app.gui.results",
    "ctdrill.app.gui.state.window",
    "ctdrill.app.gui.plots",
    "ctdrill.app.gui.scene",
    "ctdrill.app.gui.scene_plans",
    "ctdrill.app.gui.problems",
    "ctdrill.app.gui.readouts",
    "ctdrill.app.gui.slice_overlays",
    "ctdrill.app.gui.planning",
    "ctdrill.app.gui.canal_edit",
    "ctdrill.app.gui.debrief",
    "ctdrill.app.gui.rehearsal",
    "ctdrill.app.reformat.draw",
    "ctdrill.app.session_run",
    "ctdrill.app.search.suggest",
    "ctdrill.app.teleop",
    "ctdrill.app.exercise.trials",
    "ctdrill.app.exercise.bone_quality",
    "ctdrill.app.trainee.words",
    "ctdrill.app.reformat.region",
    "ctdrill.app.batch.manifest",
    "ctdrill.app.teleop_plot",
    # a rehearsal's session process (spawned): imported on its first start otherwise, with
    # the hook reading each module (0.1-0.4 s of the Start button's click)
    "multiprocessing.popen_spawn_posix",
    "multiprocessing.queues",
    "multiprocessing.sharedctypes",
    "multiprocessing.synchronize",
    "multiprocessing.resource_tracker",
    "runpy",
)


def before_qt() -> None:
    """Import :data:`QT_FREE` (call before the first PySide6 import; harmless after it)."""
    for name in QT_FREE:
        importlib.import_module(name)


#: The window's entry module (imported by :func:`import_window`).
WINDOW_MODULE = "ctdrill.app.gui.app"


def import_window() -> None:
    """Import the window (:func:`before_qt`, then Qt and the window's modules) with the cyclic
    garbage collector paused, then frozen (``gc.freeze``): the imports make about a million
    objects that live as long as the process and few cycles, and each full collection over
    them held every thread 90-260 ms (0.1-0.3 s of a launch; stalls of the window while numba
    loads in the background). Later collections scan only what was made after. Nothing is
    done when the window is imported already."""
    if WINDOW_MODULE in sys.modules:
        return
    enabled = gc.isenabled()
    gc.disable()
    try:
        before_qt()
        importlib.import_module(WINDOW_MODULE)
    finally:
        gc.freeze()
        _FROZE[0] = True
        if enabled:
            gc.enable()


#: :func:`import_window` froze the window's imports in this process (``ctdrill gui``).
_FROZE: list[bool] = [False]
#: The kernels' objects were frozen too (:func:`freeze_kernels`).
_KERNELS_FROZEN: list[bool] = [False]


def freeze_kernels() -> bool:
    """Once numba and the kernels have loaded after the first draw, freeze what lives then
    (``gc.freeze``, once a process, only where :func:`import_window` froze the imports): numba
    adds ~120 k long-lived objects, and each full collection over them held every thread 26 ms
    idle (35-80 ms under load), landing now and then in a click or a drag. What is frozen is
    never collected as a cycle: a series replaced later is freed by reference counting (a
    test holds it), and the first draw's cyclic garbage (a few hundred overlay artists) stays.
    Returns whether it froze."""
    if not _FROZE[0] or _KERNELS_FROZEN[0]:
        return False
    _KERNELS_FROZEN[0] = True
    gc.freeze()
    return True
