"""The ctdrill main window: wiring only.

The state lives in one :class:`~ctdrill.app.gui.document.Document` (volume, plan, path result,
rehearsal); the views (:data:`ctdrill.app.gui.views.VIEWS`) observe it; the
:class:`~ctdrill.app.gui.controller.Controller` runs the headless computations in worker threads.
The window lays the views out, owns the menus, the dialogs and the status line, and turns
file actions (open a series or a plan, save, screenshots) into document changes.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from functools import partial
from pathlib import Path

from PySide6.QtCore import QSettings, Qt, QThreadPool, Signal
from PySide6.QtGui import QAction, QCloseEvent, QDragEnterEvent, QDropEvent, QImage
from PySide6.QtWidgets import (
    QInputDialog,
    QMainWindow,
    QMessageBox,
    QProgressDialog,
    QSplitter,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.exercise.trials import TrialCard
from ctdrill.app.gui import compute
from ctdrill.app.gui.blind import apply_aids, refuse_trial_ct
from ctdrill.app.gui.controller import Controller
from ctdrill.app.gui.document import Document, ViewContext
from ctdrill.app.gui.first_draw import FirstDraw
from ctdrill.app.gui.menus import build_menus, fill_recent
from ctdrill.app.gui.plan_panel import PlanPanel
from ctdrill.app.gui.plots_view import PlotsView
from ctdrill.app.gui.recent import RecentFolders
from ctdrill.app.gui.rehearsal_panel import RehearsalPanel
from ctdrill.app.gui.report_action import ReportCommand
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.screenshot import grab_window
from ctdrill.app.gui.series_panel import SeriesPanel
from ctdrill.app.gui.slice_grid import SliceGrid
from ctdrill.app.gui.slices import SliceImage
from ctdrill.app.gui.suggest_panel import SuggestPanel
from ctdrill.app.gui.view3d import View3D
from ctdrill.app.gui.views import VIEWS, build_views
from ctdrill.app.gui.workers import StepQueue
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.load import load_plan_set
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.plan.write import write_plans

#: On close, how long to let a running load or computation finish, ms.
CLOSE_WAIT_MS = 5000
#: What the status line says while no trajectory exists.
PLACE_TRAJECTORY = (
    "No trajectory yet: right-click the target on a slice view, Shift+right-click the entry "
    "(or File > Open plan)."
)


class MainWindow(QMainWindow):
    """The desktop application window."""

    path_updated = Signal()  # a new path result is drawn (plots, 3D, slices)
    volume_loaded = Signal()
    load_failed = Signal(str)  # the error message
    path_failed = Signal(str)  # no path for the plan (the error message)
    surface_updated = Signal()
    undo_action: QAction  # Edit > Undo / Redo (menus.build_menus)
    redo_action: QAction

    def __init__(self, settings: QSettings | None = None) -> None:
        super().__init__()
        self.setWindowTitle("ctdrill")
        self.setAcceptDrops(True)
        self.settings = settings if settings is not None else QSettings("ctdrill", "ctdrill")
        self.recent = RecentFolders(self.settings)
        self.last_error = ""
        self.load_error: ValueError | None = None  # bad input met while loading a series
        #: Ask which series to open when a folder holds several (else the largest is taken).
        self.ask_series = True
        #: No modal dialogs (``--screenshot`` / ``--quit-after-s`` runs); bugs are kept here.
        self.unattended = False
        self.internal_error = ""
        self.progress: QProgressDialog | None = None
        #: The blind trial shown, if the plan is one (:mod:`ctdrill.app.gui.blind`).
        self.blind_trial: TrialCard | None = None
        self.instructor = False  # ``ctdrill gui --key``: a trial's CT opens openly

        self.doc = Document(self)
        #: UI-thread drawing steps, one per event-loop pass (no view holds the thread long).
        self.ui_steps = StepQueue(self)
        self.views = build_views(ViewContext(self.doc, self.ui_steps, self._status))
        self.controller = Controller(self.doc, parent=self)
        self._lay_out()
        self.view3d: View3D = self.views["3d"]  # type: ignore[assignment]
        self.slice_grid: SliceGrid = self.views["slices"]  # type: ignore[assignment]
        self.plot_canvas: PlotsView = self.views["plots"]  # type: ignore[assignment]
        self.plan_panel: PlanPanel = self.views["plan"]  # type: ignore[assignment]
        self.rehearsal: RehearsalPanel = self.views["rehearsal"]  # type: ignore[assignment]
        self.series_panel: SeriesPanel = self.views["series"]  # type: ignore[assignment]
        self.suggest_panel: SuggestPanel = self.views["suggest"]  # type: ignore[assignment]
        self.slice_canvases = self.slice_grid.canvases
        self.slices_updated = self.slice_grid.slices_updated
        self.warnings_list = self.series_panel.warnings_list
        self.block_label = self.series_panel.block_label
        self.plan_panel.add_canal_toggled.connect(self.slice_grid.set_canal_mode)
        self.rehearsal.exercise.aids_changed.connect(partial(apply_aids, self))

        # Connected after the views: the steps pushed here run after theirs.
        self.doc.path_changed.connect(self._path_changed)
        self.doc.surface_changed.connect(lambda _s: self.surface_updated.emit())
        self.doc.edit_refused.connect(self._status)
        self.report_command = ReportCommand(self.doc, self)  # File > Report
        self.report_command.finished.connect(self._status)
        self.controller.loaded.connect(self._loaded)
        self.controller.failed.connect(self._stage_failed)
        self.recent_menu = build_menus(self)
        #: numba and the kernels load once the first series is drawn (gui/first_draw.py).
        self.first_draw = FirstDraw(self)
        self._status("Open a DICOM folder (File > Open, or drop it here).")

    def _lay_out(self) -> None:
        """Place the views by area (see :mod:`ctdrill.app.gui.views`)."""
        top = QSplitter(Qt.Orientation.Horizontal)
        left = QSplitter(Qt.Orientation.Vertical)
        pages = QTabWidget()  # the main views on the first page, "page" views beside
        pages.addTab(top, "3D and slices")
        tabs = QTabWidget()
        tabs.setMinimumWidth(330)
        column = QWidget()
        box = QVBoxLayout(column)
        box.setContentsMargins(0, 0, 0, 0)
        box.setSpacing(2)
        for spec in VIEWS:
            widget = self.views[spec.key]
            if spec.area == "banner":
                box.addWidget(widget)
            elif spec.area == "main":
                top.addWidget(widget)
            elif spec.area == "page":
                pages.addTab(widget, spec.title)
            elif spec.area == "bottom":
                left.addWidget(widget)
            else:
                tabs.addTab(widget, spec.title)
        left.insertWidget(0, pages)
        left.setSizes([520, 280])
        top.setSizes([560, 440])
        box.addWidget(left, 1)
        main = QSplitter(Qt.Orientation.Horizontal)
        main.addWidget(column)
        main.addWidget(tabs)
        main.setSizes([1000, 340])
        self.setCentralWidget(main)
        self.tabs = tabs
        self.pages = pages

    # ------------------------------------------------------------------ state (the document's)
    @property
    def volume(self) -> CTVolume | None:
        """The open series."""
        return self.doc.volume

    @property
    def volume_path(self) -> str:
        """Where the open series was loaded from."""
        return self.doc.volume_path

    @property
    def plan(self) -> Plan | None:
        """The plan (None: no trajectory placed yet)."""
        return self.doc.plan

    @property
    def view(self) -> PathView | None:
        """The path result of the plan (None: not computed, or not computable)."""
        return self.doc.path

    @property
    def slices(self) -> dict[str, SliceImage]:
        """The planes the slice views show."""
        return self.slice_grid.slices

    def recent_folders(self) -> list[str]:
        """Recently opened folders, most recent first."""
        return self.recent.items()

    def _remember(self, path: str) -> None:
        self.recent.remember(path)
        fill_recent(self)

    def _status(self, text: str) -> None:
        self.statusBar().showMessage(text)

    # ------------------------------------------------------------------ opening
    def open_folder(self, path: str | os.PathLike[str], *, series_uid: str | None = None) -> None:
        """Load a series in the background, with a cancellable progress dialog."""
        if self.doc.rehearsing:
            self._status("a rehearsal runs: stop it before opening another series")
            return
        folder = str(path)
        if refuse_trial_ct(self, Path(folder)):  # only in its blind trial (gui/blind.py)
            return
        self.controller.load(folder, series_uid=series_uid, ask_series=self.ask_series)
        self.progress = QProgressDialog(f"Loading {folder} ...", "Cancel", 0, 0, self)
        self.progress.setWindowModality(Qt.WindowModality.WindowModal)
        self.progress.setMinimumDuration(300)
        self.progress.canceled.connect(self._cancel_load)
        self._status(f"loading {folder}")

    def _cancel_load(self) -> None:
        self.controller.load_runner.cancel()
        self._status("loading cancelled")

    def _close_progress(self) -> None:
        if self.progress is not None:
            self.progress.canceled.disconnect(self._cancel_load)
            self.progress.reset()
            self.progress = None

    def choose_series(self, choice: compute.SeriesChoice) -> str | None:
        """Ask which CT stack to open; returns its SeriesInstanceUID (None: cancelled)."""
        labels = [
            f"{s.n_slices} slices {s.cols}x{s.rows}  {s.description or '(no description)'}  "
            f"[{s.series_uid}]"
            for s in choice.series
        ]
        label, ok = QInputDialog.getItem(
            self, "Several series", f"{choice.path} holds several CT series:", labels, 0, False
        )
        if not ok:
            return None
        return choice.series[labels.index(label)].series_uid

    def _loaded(self, loaded: compute.Loaded | compute.SeriesChoice) -> None:
        self._close_progress()
        if isinstance(loaded, compute.SeriesChoice):
            uid = self.choose_series(loaded)
            if uid is None:
                self._status("loading cancelled")
            else:
                self.open_folder(loaded.path, series_uid=uid)
            return
        if self.doc.volume is not loaded.volume:  # refused: a rehearsal runs
            return
        self._remember(loaded.path)
        trial = self.blind_trial
        self.setWindowTitle(
            f"ctdrill - {Path(loaded.path).name}"
            if trial is None
            else f"ctdrill: blind trial {trial.trial}"
        )
        dims = "x".join(str(n) for n in loaded.volume.dims)
        self._status(
            PLACE_TRAJECTORY
            if self.doc.plan is None
            else f"loaded {loaded.path}: {dims}, {len(loaded.volume.warnings)} warning(s)"
        )
        self.volume_loaded.emit()

    def _stage_failed(self, stage: str, exc: BaseException, tb: str) -> None:
        if stage == "load":
            self._close_progress()
            if isinstance(exc, ValueError):
                self.load_error = exc
        self._failed(exc, tb)
        if stage == "load":
            self.load_failed.emit(str(exc))
        elif stage == "path":
            self.path_failed.emit(str(exc))
        elif stage == "surface":
            self.view3d.surface_failed()

    def _failed(self, exc: BaseException, tb: str) -> None:
        self.last_error = str(exc)
        if isinstance(exc, ValueError):  # the packages' *InputError family: bad input
            self._status(f"error: {exc}")
        else:
            self.internal_error = tb or repr(exc)
            self._status(f"internal error: {exc!r}")
            if self.unattended:
                sys.stderr.write(f"ctdrill gui: internal error\n{tb}\n")
            else:
                QMessageBox.critical(self, "ctdrill: internal error", tb)

    def open_plan(self, path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]) -> bool:
        """Read a plan (ctdrill-plan/1, Slicer markups, segmentations; several files or a
        folder merge, :func:`~ctdrill.imaging.plan.load.load_plan_set`) with every trajectory
        it holds, and show it (the first trajectory current); a plan that cannot be read is an
        error dialog (the plan shown stays). Returns True when the plan is shown."""
        paths = [path] if isinstance(path, str | os.PathLike) else list(path)
        try:
            plans = load_plan_set(paths)
        except ValueError as exc:
            self.last_error = str(exc)
            self._status(f"error: {exc}")
            if not self.unattended:
                QMessageBox.warning(self, "ctdrill: cannot open the plan", str(exc))
            return False
        shown = self.use_plans(plans, ", ".join(str(p) for p in paths))
        if shown:
            self.show_trial(paths)
        return shown

    def show_trial(self, paths: Sequence[str | os.PathLike[str]]) -> None:
        """A blind trial's plan hides what gives the bone away (:mod:`ctdrill.app.gui.blind`)."""
        from ctdrill.app.gui.blind import show_trial

        show_trial(self, paths)

    def use_plans(self, plans: Sequence[Plan], source: str = "") -> bool:
        """Show ``plans`` (read from ``source``; a new undo history), the first one current,
        its path computed at once."""
        if not plans or not self.doc.set_plans(tuple(plans)):
            return False
        self.view3d.refocus_next = True
        self.controller.recompute()
        count = f" ({len(plans)} trajectories)" if len(plans) > 1 else ""
        self._status(f"plan {source or plans[0].name}{count}")
        return True

    def use_plan(self, plan: Plan, source: str = "") -> bool:
        """Show the one-trajectory plan ``plan`` (:meth:`use_plans`)."""
        return self.use_plans((plan,), source)

    def save_plan(self, path: str | os.PathLike[str]) -> None:
        """Write every trajectory (``.mrk.json``: Slicer markups, else ctdrill-plan/1)."""
        if not self.doc.plans:
            return
        try:
            uid = None if self.doc.volume is None else self.doc.volume.info.series_uid
            write_plans(self.doc.plans, path, series_uid=uid)  # records the series, hashed
        except (ValueError, OSError) as exc:
            self._status(f"error: {exc}")
            return
        self._status(f"saved {path}")

    # ------------------------------------------------------------------ drag and drop
    def dragEnterEvent(self, event: QDragEnterEvent) -> None:
        if event.mimeData().hasUrls():
            event.acceptProposedAction()

    def dropEvent(self, event: QDropEvent) -> None:
        for url in event.mimeData().urls():
            self.open_dropped(url.toLocalFile())
            break

    def open_dropped(self, path: str) -> None:
        """A folder opens as a series, a ``.json`` as a plan, a NIfTI, NRRD or MetaImage file
        as the CT, any other file its folder."""
        p = Path(path)
        if p.is_dir():
            self.open_folder(p)
        elif p.name.lower().endswith(".json"):
            self.open_plan(p)
        elif p.is_file():
            self.open_folder(p if compute.is_volume_file(p) else p.parent)

    # ------------------------------------------------------------------ results
    def _path_changed(self, view: PathView | None) -> None:
        if view is None:
            return

        def finish() -> None:  # after the views' drawing steps (the plots say the stop)
            if self.doc.path is view:
                self.path_updated.emit()

        self.ui_steps.push(finish)

    def set_surface_preset(self, iso_hu: float) -> None:
        """Re-contour the bone surface at ``iso_hu`` (in the background)."""
        self._status(f"bone surface at {iso_hu:g} HU ...")
        self.controller.set_iso(iso_hu)

    def set_window_preset(self, label: str) -> None:
        """Apply a window/level preset to the slice views."""
        self.slice_grid.set_window_preset(label)

    def write_report(self, path: str) -> bool:
        """Write the PDF report of the plan to ``path`` in the background (File > Report)."""
        return self.report_command.write(path)

    def suggest_axes(self) -> bool:
        """Show the *Suggest* tab and search nearby axes with its settings (background)."""
        self.tabs.setCurrentWidget(self.suggest_panel)
        return self.suggest_panel.start()

    def refocus(self) -> None:
        """Point the 3D camera and the slice planes at the trajectory again."""
        if self.view3d.scene is not None:
            self.view3d.show_scene(self.view3d.scene, refocus=True)
        if self.plan is not None:
            self.slice_grid.centre_on_drill()

    # ------------------------------------------------------------------ screenshots
    def grab_composite(self) -> QImage:
        """The whole window with the 3D view's OpenGL content composited in."""
        if not self.view3d.isVisible():  # another page is shown: no GL content to add
            return grab_window(self, [])
        self.view3d.render_now()
        return grab_window(self, [(self.view3d, self.view3d.grab_rgb())])

    def save_screenshot(self, path: str | os.PathLike[str]) -> None:
        """Write :meth:`grab_composite` to ``path`` (PNG)."""
        if not self.grab_composite().save(str(path)):
            raise OSError(f"could not write the screenshot {path}")

    def closeEvent(self, event: QCloseEvent) -> None:
        self.rehearsal.shutdown()
        self.first_draw.close()
        self.controller.cancel()
        self.slice_grid.runner.cancel()
        QThreadPool.globalInstance().waitForDone(CLOSE_WAIT_MS)
        self.view3d.close_plotter()
        super().closeEvent(event)
