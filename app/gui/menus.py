"""The window's menus and file dialogs (each action calls a window method)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any, Protocol

from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QFileDialog, QMenu, QMenuBar, QWidget

from ctdrill.app.gui.document import Document
from ctdrill.imaging.display import SURFACE_PRESETS, WINDOW_PRESETS


class MenuWindow(Protocol):
    """What the menus use of the main window (:class:`ctdrill.app.gui.main_window.MainWindow`,
    which builds them): its document, the actions the menus set, and one method per item."""

    undo_action: QAction
    redo_action: QAction
    recent_menu: QMenu

    @property
    def doc(self) -> Document: ...

    def window(self) -> QWidget: ...  # the window itself: the actions' and dialogs' parent

    def menuBar(self) -> QMenuBar: ...

    def close(self) -> bool: ...

    def recent_folders(self) -> list[str]: ...

    def open_folder(self, path: str) -> None: ...

    def open_plan(self, path: str) -> bool: ...

    def save_plan(self, path: str) -> None: ...

    def save_screenshot(self, path: str) -> None: ...

    def set_surface_preset(self, iso_hu: float) -> None: ...

    def set_window_preset(self, label: str) -> None: ...

    def refocus(self) -> None: ...

    def suggest_axes(self) -> bool: ...

    def write_report(self, path: str) -> bool: ...


def _action(
    window: MenuWindow, menu: QMenu, text: str, slot: Callable[[], Any], shortcut: Any = None
) -> QAction:
    action = QAction(text, window.window())
    if shortcut is not None:
        action.setShortcut(shortcut)
    action.triggered.connect(lambda _checked=False: slot())
    menu.addAction(action)
    return action


def build_menus(window: MenuWindow) -> QMenu:
    """File, Edit, View and Plan menus; returns the "Open recent" submenu (filled by
    :func:`fill_recent`)."""
    bar = window.menuBar()
    file_menu = bar.addMenu("&File")
    keys = QKeySequence.StandardKey
    _action(
        window, file_menu, "Open DICOM folder...", lambda: open_folder_dialog(window), keys.Open
    )
    _action(window, file_menu, "Open CT file...", lambda: open_ct_file_dialog(window))
    recent = file_menu.addMenu("Open recent")
    _action(window, file_menu, "Open plan...", lambda: open_plan_dialog(window), "Ctrl+Shift+O")
    _action(window, file_menu, "Save plan...", lambda: save_plan_dialog(window), keys.Save)
    _action(window, file_menu, "Save screenshot...", lambda: screenshot_dialog(window), "Ctrl+P")
    _action(window, file_menu, "Report...", lambda: report_dialog(window), "Ctrl+R")
    file_menu.addSeparator()
    _action(window, file_menu, "Quit", window.close, keys.Quit)
    edit_menu = bar.addMenu("&Edit")
    window.undo_action = _action(window, edit_menu, "Undo", window.doc.undo, "Ctrl+Z")
    window.redo_action = _action(window, edit_menu, "Redo", window.doc.redo, "Ctrl+Shift+Z")
    window.doc.history_changed.connect(partial(name_history_actions, window))
    window.doc.rehearsal_changed.connect(lambda _running: name_history_actions(window))
    name_history_actions(window)
    view_menu = bar.addMenu("&View")
    surf = view_menu.addMenu("Bone surface")
    for label, iso in SURFACE_PRESETS.items():
        _action(window, surf, label, partial(window.set_surface_preset, iso))
    wl = view_menu.addMenu("Window/level")
    for label in WINDOW_PRESETS:
        _action(window, wl, label, partial(window.set_window_preset, label))
    _action(window, view_menu, "Focus on trajectory", window.refocus, "F")
    plan_menu = bar.addMenu("&Plan")
    _action(window, plan_menu, "Suggest axes", window.suggest_axes, "Ctrl+G")
    window.recent_menu = recent
    fill_recent(window)
    return recent


def name_history_actions(window: MenuWindow) -> None:
    """Edit > Undo / Redo say which edit they revert or repeat, enabled only when they can
    (never while a rehearsal locks the plan)."""
    doc = window.doc
    for action, verb, name in (
        (window.undo_action, "Undo", doc.history.undo_name),
        (window.redo_action, "Redo", doc.history.redo_name),
    ):
        action.setText(verb if name is None else f"{verb} {name}")
        action.setEnabled(name is not None and not doc.rehearsing)


def fill_recent(window: MenuWindow) -> None:
    """Rebuild "Open recent" from the window's recent-folder list."""
    menu = window.recent_menu
    menu.clear()
    folders = window.recent_folders()
    for path in folders:
        _action(window, menu, path, partial(window.open_folder, path))
    menu.setEnabled(bool(folders))


def open_folder_dialog(window: MenuWindow) -> None:
    """Ask for a DICOM folder (starting at the most recent one) and open it."""
    start = (window.recent_folders() or [str(Path.home())])[0]
    path = QFileDialog.getExistingDirectory(window.window(), "Open DICOM folder", start)
    if path:
        window.open_folder(path)


#: The CT files the file dialog offers (the type is read from the content: docs/volumes.md).
CT_FILE_FILTER = "CT volumes (*.nii *.nii.gz *.nrrd *.nhdr *.mha *.mhd *.dcm);;All files (*)"


def open_ct_file_dialog(window: MenuWindow) -> None:
    """Ask for a CT file (NIfTI, NRRD, MetaImage or one DICOM file) and open it."""
    path, _ = QFileDialog.getOpenFileName(window.window(), "Open CT file", "", CT_FILE_FILTER)
    if path:
        window.open_folder(path)


def open_plan_dialog(window: MenuWindow) -> None:
    """Ask for a plan file and open it."""
    path, _ = QFileDialog.getOpenFileName(
        window.window(), "Open plan", "", "Plans (*.json *.mrk.json);;All files (*)"
    )
    if path:
        window.open_plan(path)


def save_plan_dialog(window: MenuWindow) -> None:
    """Ask where to save the plan (``.mrk.json``: 3D Slicer markups)."""
    if not window.doc.plans:
        return
    path, _ = QFileDialog.getSaveFileName(
        window.window(),
        "Save plan",
        "plan.json",
        "ctdrill plan (*.json);;3D Slicer markups (*.mrk.json)",
    )
    if path:
        window.save_plan(path)


def report_dialog(window: MenuWindow) -> None:
    """Ask where to write the PDF report of the plan (``ctdrill report``'s clinical summary)."""
    path, _ = QFileDialog.getSaveFileName(
        window.window(), "Write report", "report.pdf", "PDF (*.pdf)"
    )
    if path:
        window.write_report(path)


def screenshot_dialog(window: MenuWindow) -> None:
    """Ask where to save a screenshot of the window."""
    path, _ = QFileDialog.getSaveFileName(
        window.window(), "Save screenshot", "ctdrill.png", "PNG (*.png)"
    )
    if path:
        window.save_screenshot(path)
