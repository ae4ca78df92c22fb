"""The Series tab: why rehearsal is blocked, the loader's warnings, the path's warnings (with the
implant's and every drill's, :mod:`ctdrill.app.gui.problems`); each warning once and whole
(wrapped to the tab's width, scrollable; a view of the document)."""

from __future__ import annotations

from collections.abc import Iterable

from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.results import PathView, block_reason
from ctdrill.app.gui.wrapped_list import WrappedList
from ctdrill.imaging import LoadWarning


def unique_warnings(
    warnings: Iterable[LoadWarning], already: Iterable[LoadWarning] = ()
) -> list[LoadWarning]:
    """``warnings`` without repeats (same code and message) and without those in ``already``,
    in their first order."""
    seen = {(w.code, w.message) for w in already}
    out = []
    for w in warnings:
        if (w.code, w.message) not in seen:
            seen.add((w.code, w.message))
            out.append(w)
    return out


def path_warnings(view: PathView) -> tuple[LoadWarning, ...]:
    """The path's warnings, then the implant check's and the plan problems' (repeats are
    dropped by :func:`unique_warnings`)."""
    extra = () if view.implant is None else view.implant.warnings
    return (*view.result.warnings, *extra, *view.problems)


class SeriesPanel(QWidget):
    """Warnings of the open series and of the planned path, and the blocking reason."""

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.block_label = QLabel("")
        self.block_label.setWordWrap(True)
        self.block_label.setStyleSheet("color:#b71c1c; font-weight:bold")
        # every warning whole: wrapped (long paths too), as tall as it needs, scrollable
        self.warnings_list = WrappedList()
        self.path_warnings_list = WrappedList()
        lay = QVBoxLayout(self)
        lay.addWidget(self.block_label)
        lay.addWidget(QLabel("Loader warnings"))
        lay.addWidget(self.warnings_list)
        lay.addWidget(QLabel("Along the drill path"))
        lay.addWidget(self.path_warnings_list)
        ctx.doc.volume_changed.connect(lambda volume: self.set_load_warnings(volume.warnings))
        ctx.doc.volume_changed.connect(lambda _volume: self._path(None))
        ctx.doc.plan_changed.connect(lambda _plan: self._path(None))
        ctx.doc.path_changed.connect(self._path)

    def _path(self, view: PathView | None) -> None:
        doc = self.ctx.doc
        own = view if view is not None and view.plan is doc.plan else None
        self.set_block(block_reason(doc.volume, doc.plan, own, doc.path_error))
        loader = doc.volume.warnings if doc.volume is not None else ()
        self.set_path_warnings(() if own is None else path_warnings(own), loader)

    def set_load_warnings(self, warnings: tuple[LoadWarning, ...]) -> None:
        """Show the loader's warnings (``code: message``), each once."""
        self.warnings_list.clear()
        for w in unique_warnings(warnings):
            self.warnings_list.addItem(f"{w.code}: {w.message}")

    def set_path_warnings(
        self, warnings: tuple[LoadWarning, ...], already: tuple[LoadWarning, ...]
    ) -> None:
        """Show the path's warnings that the loader list does not already hold, each once."""
        self.path_warnings_list.clear()
        for w in unique_warnings(warnings, already):
            self.path_warnings_list.addItem(f"{w.code}: {w.message}")

    def set_block(self, reason: str | None) -> None:
        """Say why rehearsal is disabled (None: it is not)."""
        self.block_label.setText("" if not reason else f"Rehearsal disabled: {reason}")
