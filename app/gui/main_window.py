"""The ctdrill main window: 3D view, four slice views, depth plots, plan and rehearsal panels.

Every action calls a headless function (``ctdrill.app.gui.compute``, ``ctdrill.app.gui.planning``,
``ctdrill.app.pipeline``, ``ctdrill.imaging.plan.types``, ``ctdrill.app.export``); loading and path
planning run in a worker thread (latest wins), so the UI thread stays responsive.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import QSettings, Qt, QThreadPool, Signal
from PySide6.QtGui import QCloseEvent, QDragEnterEvent, QDropEvent, QImage
from PySide6.QtWidgets import (
    QGridLayout,
    QInputDialog,
    QMainWindow,
    QMessageBox,
    QProgressDialog,
    QSplitter,
    QTabWidget,
    QWidget,
)

from ctdrill.app.gui import compute, planning
from ctdrill.app.gui.menus import build_menus, fill_recent
from ctdrill.app.gui.plan_panel import PlanPanel
from ctdrill.app.gui.plots import draw_depth_plots, set_live_depth
from ctdrill.app.gui.recent import RecentFolders
from ctdrill.app.gui.rehearsal_panel import RehearsalPanel
from ctdrill.app.gui.results import PathView, block_reason, compute_path_view
from ctdrill.app.gui.scene import SceneInput
from ctdrill.app.gui.screenshot import grab_window
from ctdrill.app.gui.series_panel import SeriesPanel
from ctdrill.app.gui.slice_view import SliceCanvas
from ctdrill.app.gui.slices import VIEWS, WINDOW_PRESETS, SliceImage, volume_center_lps
from ctdrill.app.gui.view3d import View3D
from ctdrill.app.gui.workers import Debouncer, Runner, StepQueue
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.types import Plan, load_one_plan, save_plan

#: On close, how long to let a running load or computation finish, ms.
CLOSE_WAIT_MS = 5000
#: Delay between the last plan edit and the recomputation, ms.
DEBOUNCE_MS = 150


class MainWindow(QMainWindow):
    """The desktop application window."""

    path_updated = Signal()  # a new path result is shown (plots, 3D, slices)
    volume_loaded = Signal()
    load_failed = Signal(str)  # the error message
    path_failed = Signal(str)  # no path for the plan (the error message)
    surface_updated = Signal()
    slices_updated = Signal()

    def __init__(self, settings: QSettings | None = None) -> None:
        super().__init__()
        self.setWindowTitle("ctdrill")
        self.setAcceptDrops(True)
        self.settings = settings if settings is not None else QSettings("ctdrill", "ctdrill")
        self.recent = RecentFolders(self.settings)
        self.volume: CTVolume | None = None
        self.volume_path = ""
        self.plan: Plan | None = None
        self.view: PathView | None = None
        self.slices: dict[str, SliceImage] = {}
        self.iso_hu = 300.0
        self.window_level = WINDOW_PRESETS["bone"]
        self.last_error = ""
        self.load_error: ValueError | None = None  # bad input met while loading a series
        #: Ask which series to open when a folder holds several (else the largest is taken).
        self.ask_series = True
        #: No modal dialogs (``--screenshot`` / ``--quit-after-s`` runs); bugs are kept here.
        self.unattended = False
        self.internal_error = ""
        self._refocus_next = False
        self._slice_key: tuple[object, ...] | None = None

        self.view3d = View3D()
        #: UI-thread drawing steps, one per event-loop pass (see ``_slices_done``, ``_path_done``).
        self.ui_steps = StepQueue()
        self.slice_canvases: dict[str, SliceCanvas] = {
            v: SliceCanvas(v, steps=self.ui_steps) for v in VIEWS
        }
        slice_box = QWidget()
        grid = QGridLayout(slice_box)
        grid.setContentsMargins(0, 0, 0, 0)
        grid.setSpacing(2)
        for n, v in enumerate(VIEWS):
            grid.addWidget(self.slice_canvases[v], n // 2, n % 2)
            self.slice_canvases[v].point_moved.connect(self._handle_moved)
            self.slice_canvases[v].clicked.connect(self._canal_click)
        self.plot_fig = Figure(figsize=(6, 4), dpi=80)
        self.plot_canvas = FigureCanvasQTAgg(self.plot_fig)
        draw_depth_plots(self.plot_fig, None, message="open a DICOM folder")

        self.plan_panel = PlanPanel()
        self.plan_panel.plan_edited.connect(self.set_plan)
        self.plan_panel.edit_rejected.connect(self._status)
        self.plan_panel.add_canal_toggled.connect(self._canal_mode)
        self.rehearsal = RehearsalPanel()
        self.rehearsal.depth_changed.connect(self._live_depth)
        self.series_panel = SeriesPanel()
        self.warnings_list = self.series_panel.warnings_list
        self.block_label = self.series_panel.block_label
        self.tabs = QTabWidget()
        self.tabs.addTab(self.plan_panel, "Plan")
        self.tabs.addTab(self.rehearsal, "Rehearsal")
        self.tabs.addTab(self.series_panel, "Series")
        self.tabs.setMinimumWidth(330)

        top = QSplitter(Qt.Orientation.Horizontal)
        top.addWidget(self.view3d)
        top.addWidget(slice_box)
        top.setSizes([560, 440])
        left = QSplitter(Qt.Orientation.Vertical)
        left.addWidget(top)
        left.addWidget(self.plot_canvas)
        left.setSizes([520, 280])
        main = QSplitter(Qt.Orientation.Horizontal)
        main.addWidget(left)
        main.addWidget(self.tabs)
        main.setSizes([1000, 340])
        self.setCentralWidget(main)

        self.load_runner = Runner(self._loaded, self._load_failed, parent=self)
        self.path_runner = Runner(self._path_done, self._path_failed, parent=self)
        self.slice_runner = Runner(self._slices_done, self._failed, parent=self)
        self.surface_runner = Runner(self._surface_done, self._failed, parent=self)
        self.debounce = Debouncer(self._recompute, DEBOUNCE_MS, parent=self)
        self.ui_steps.setParent(self)
        self.progress: QProgressDialog | None = None
        self.recent_menu = build_menus(self)
        self._status("Open a DICOM folder (File > Open, or drop it here).")

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
        folder = str(path)
        iso, ask = self.iso_hu, self.ask_series
        self.load_runner.submit(
            lambda: compute.load_case(folder, series_uid=series_uid, iso_hu=iso, ask_series=ask)
        )
        self.progress = QProgressDialog(f"Loading {folder} ...", "Cancel", 0, 0, self)
        self.progress.setWindowModality(Qt.WindowModality.WindowModal)
        self.progress.setMinimumDuration(300)
        self.progress.canceled.connect(self._cancel_load)
        self._status(f"loading {folder}")

    def _cancel_load(self) -> None:
        self.load_runner.cancel()
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
        self.volume = loaded.volume
        self.volume_path = loaded.path
        self._slice_key = None
        self._remember(loaded.path)
        self.view3d.set_surface(loaded.surface, redraw=False)  # drawn with the new path
        self.series_panel.set_load_warnings(loaded.volume.warnings)
        if self.plan is None:
            center = volume_center_lps(loaded.volume)
            self.plan = planning.default_plan(center)
        self.setWindowTitle(f"ctdrill - {Path(loaded.path).name}")
        self._status(
            f"loaded {loaded.path}: {loaded.volume.dims[0]}x{loaded.volume.dims[1]}x"
            f"{loaded.volume.dims[2]}, {len(loaded.volume.warnings)} warning(s)"
        )
        self.volume_loaded.emit()
        self.set_plan(self.plan, now=True)

    def _load_failed(self, exc: BaseException, tb: str) -> None:
        if isinstance(exc, ValueError):
            self.load_error = exc
        self._failed(exc, tb)
        self.load_failed.emit(str(exc))

    def _failed(self, exc: BaseException, tb: str) -> None:
        self._close_progress()
        self.last_error = str(exc)
        if isinstance(exc, ValueError):  # the packages' *InputError family: bad input
            self._status(f"error: {exc}")
            self._show_block(str(exc))
        else:
            self.internal_error = tb or repr(exc)
            self._status(f"internal error: {exc!r}")
            if self.unattended:
                sys.stderr.write(f"ctdrill gui: internal error\n{tb}\n")
            else:
                QMessageBox.critical(self, "ctdrill: internal error", tb)

    def open_plan(self, path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]) -> None:
        """Read a plan (ctdrill-plan/1, Slicer markups, segmentations; several files or a
        folder merge into one trajectory) and show it."""
        paths = [path] if isinstance(path, str | os.PathLike) else list(path)
        try:
            plan = load_one_plan(paths)
        except ValueError as exc:
            self._failed(exc, "")
            return
        self._status(f"plan {', '.join(str(p) for p in paths)}")
        self.set_plan(plan, now=True, refocus=True)

    def save_plan(self, path: str | os.PathLike[str]) -> None:
        """Write the plan (``.mrk.json``: Slicer markups, else ctdrill-plan/1)."""
        if self.plan is None:
            return
        try:
            uid = None if self.volume is None else self.volume.info.series_uid
            save_plan(self.plan, path, series_uid=uid)  # records the series, hashed
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
        """A folder opens as a series, a ``.json`` as a plan, any other file its folder."""
        p = Path(path)
        if p.is_dir():
            self.open_folder(p)
        elif p.name.lower().endswith(".json"):
            self.open_plan(p)
        elif p.is_file():
            self.open_folder(p.parent)

    # ------------------------------------------------------------------ plan and views
    def set_plan(self, plan: Plan, *, now: bool = False, refocus: bool = False) -> None:
        """Show ``plan``; slices and the path are recomputed (debounced unless ``now``)."""
        self.plan = plan
        self.plan_panel.set_plan(plan)
        self._refocus_next = refocus
        if now:
            self._recompute()
        else:
            self.debounce.poke()

    def _recompute(self) -> None:
        volume, plan = self.volume, self.plan
        if volume is None or plan is None:
            return
        key = compute.slice_key(volume, plan)
        if key != self._slice_key:  # the planes moved: reslice; else only the overlays change
            self._slice_key = key
            self.slice_runner.submit(lambda: compute.slice_views(volume, plan))
        else:
            self._draw_overlays()
        self.path_runner.submit(lambda: compute_path_view(volume, plan))
        self._status("computing the path ...")

    def _slices_done(self, slices: dict[str, SliceImage]) -> None:
        self.slices = slices
        # One slice view per event-loop pass (each is resliced, overlaid and drawn), so the
        # UI thread is never held for all four canvases at once.
        for name in slices:
            self.ui_steps.push(partial(self._show_slice, slices, name))
        self.ui_steps.push(lambda: self._slices_shown(slices))

    def _show_slice(self, slices: dict[str, SliceImage], name: str) -> None:
        if slices is not self.slices:
            return
        level, width = self.window_level
        plan = self.plan
        canvas = self.slice_canvases[name]
        canvas.show_slice(slices[name], level_hu=level, width_hu=width)
        if plan is not None:  # the trajectory in the middle of the field of view
            canvas.focus_on((plan.entry_lps + plan.target_lps) / 2.0)
        self._draw_overlays(only=name)

    def _slices_shown(self, slices: dict[str, SliceImage]) -> None:
        if slices is self.slices:
            self.slices_updated.emit()

    def _draw_overlays(self, only: str | None = None) -> None:
        """Overlay the plan on every slice view (or on view ``only``)."""
        plan = self.plan
        if plan is None:
            return
        view = self.view if self.view is not None and self.view.plan is plan else None
        stop = None if view is None else plan.point_at_depth_lps(view.curves.stop_depth_mm)
        lms = planning.landmark_geometries(plan, None if view is None else view.min_clearance_mm)
        for name, canvas in self.slice_canvases.items():
            if only is not None and name != only:
                continue
            canvas.set_overlays(
                entry_lps=plan.entry_lps, target_lps=plan.target_lps, stop_lps=stop, landmarks=lms
            )

    def _path_done(self, view: PathView) -> None:
        plan = self.plan
        if plan is None or view.plan is not plan:
            return
        self.view = view
        # Four steps, one per event-loop pass, so that paints and timers run in between and
        # the UI thread is never held for the whole update (on software GL the scene build
        # and the frame are each tens of ms).
        self.ui_steps.push(lambda: self._show_plots(view))
        self.ui_steps.push(lambda: self._show_scene(view))
        self.ui_steps.push(lambda: self._render_scene(view))
        self.ui_steps.push(lambda: self._finish_path(view))

    def _show_plots(self, view: PathView) -> None:
        if view is not self.view:
            return
        draw_depth_plots(self.plot_fig, view.curves)
        self.ui_steps.push(self.plot_canvas.draw)  # ~50 ms of Agg: a pass of its own

    def _show_scene(self, view: PathView) -> None:
        if view is not self.view:
            return
        self._draw_scene(view.plan, view, render=False)

    def _render_scene(self, view: PathView) -> None:
        if view is not self.view:
            return
        self.view3d.render_now()

    def _draw_scene(self, plan: Plan, view: PathView | None, *, render: bool = True) -> None:
        """The 3D scene of ``plan``, with the stop point and clearances when computed."""
        scene = SceneInput(
            entry_lps=plan.entry_lps,
            target_lps=plan.target_lps,
            diameter_mm=plan.drill.diameter_mm,
            tip_length_mm=plan.drill.tip_length_mm,
            stop_depth_mm=None if view is None else view.curves.stop_depth_mm,
            landmarks=planning.landmark_geometries(
                plan, None if view is None else view.min_clearance_mm
            ),
        )
        self.view3d.show_scene(scene, refocus=self._refocus_next, render=render)
        self._refocus_next = False

    def _path_failed(self, exc: BaseException, tb: str) -> None:
        """No path for this plan: still show the anatomy and the plan, and say why."""
        self.view = None
        self._failed(exc, tb)
        draw_depth_plots(self.plot_fig, None, message=f"no force profile: {exc}")
        self.plot_canvas.draw_idle()
        if self.plan is not None and self.volume is not None:
            self._draw_scene(self.plan, None)
            self._draw_overlays()
        self.path_failed.emit(str(exc))

    def _finish_path(self, view: PathView) -> None:
        if view is not self.view:
            return
        plan = view.plan
        self.series_panel.set_path_warnings(
            view.result.warnings, self.volume.warnings if self.volume else ()
        )
        self.plan_panel.set_plan(plan, view.min_clearance_mm)
        self._draw_overlays()
        reason = block_reason(self.volume, view)
        self._show_block(reason)
        self.rehearsal.set_case(self.volume, plan, view.result, blocked=reason)
        self._status(
            f"stop at {view.curves.stop_depth_mm:.2f} mm ({view.curves.stop_reason}) of "
            f"{view.curves.planned_depth_mm:.2f} mm planned"
        )
        self.path_updated.emit()

    def _live_depth(self, depth_mm: float) -> None:
        """The drill's live depth (rehearsal telemetry): 3D drill and the plots' cursor."""
        self.view3d.set_drill_depth(depth_mm)
        set_live_depth(self.plot_fig, depth_mm)
        self.plot_canvas.draw_idle()

    def _show_block(self, reason: str | None) -> None:
        self.series_panel.set_block(reason)
        if reason:
            self.rehearsal.set_blocked(reason)

    def _handle_moved(self, name: str, point_lps: np.ndarray) -> None:
        if self.plan is None:
            return
        try:
            self.set_plan(planning.move_handle(self.plan, name, point_lps))
        except ValueError as exc:
            self._status(f"error: {exc}")
            self._draw_overlays()

    def _canal_mode(self, on: bool) -> None:
        for canvas in self.slice_canvases.values():
            canvas.add_points_mode = on

    def _canal_click(self, point_lps: np.ndarray) -> None:
        if self.plan is not None:
            self.set_plan(planning.add_canal_point(self.plan, point_lps))

    def set_surface_preset(self, iso_hu: float) -> None:
        """Re-contour the bone surface at ``iso_hu`` (in the background)."""
        self.iso_hu = iso_hu
        volume = self.volume
        if volume is not None:
            self._status(f"bone surface at {iso_hu:g} HU ...")
            self.surface_runner.submit(lambda: compute.volume_surface(volume, iso_hu=iso_hu))

    def _surface_done(self, surface: Any) -> None:
        self.view3d.set_surface(surface)
        self._status(f"bone surface at {self.iso_hu:g} HU")
        self.surface_updated.emit()

    def set_window_preset(self, label: str) -> None:
        """Apply a window/level preset to the slice views."""
        self.window_level = WINDOW_PRESETS[label]
        level, width = self.window_level
        for name, img in self.slices.items():
            self.slice_canvases[name].set_window(img, level_hu=level, width_hu=width)

    def refocus(self) -> None:
        """Point the 3D camera at the trajectory again."""
        if self.view3d.scene is not None:
            self.view3d.show_scene(self.view3d.scene, refocus=True)

    # ------------------------------------------------------------------ screenshots
    def grab_composite(self) -> QImage:
        """The whole window with the 3D view's OpenGL content composited in."""
        self.view3d.render_now()
        return grab_window(self, [(self.view3d, self.view3d.grab_rgb())])

    def save_screenshot(self, path: str | os.PathLike[str]) -> None:
        """Write :meth:`grab_composite` to ``path`` (PNG)."""
        if not self.grab_composite().save(str(path)):
            raise OSError(f"could not write the screenshot {path}")

    def closeEvent(self, event: QCloseEvent) -> None:
        self.rehearsal.shutdown()
        self.load_runner.cancel()
        self.path_runner.cancel()
        self.slice_runner.cancel()
        QThreadPool.globalInstance().waitForDone(CLOSE_WAIT_MS)
        self.view3d.close_plotter()
        super().closeEvent(event)
