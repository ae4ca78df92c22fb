"""The banner over the views: shown when the planned path breaks a landmark's margin
(warning ``plan_violates_margin``) or when no path could be computed (clearance unknown); while
a trajectory is dragged it follows the dragged plan's path."""

from __future__ import annotations

from PySide6.QtWidgets import QLabel

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.results import PathView, binding_index, plan_violation

VIOLATION_STYLE = "background:#c62828; color:white; font-weight:bold; padding:6px"
UNKNOWN_STYLE = "background:#8d6e00; color:white; font-weight:bold; padding:6px"


def banner_text(view: PathView | None, path_error: str) -> tuple[str, str] | None:
    """(text, kind) of the banner for a path result (or its failure), None: no banner.
    ``kind`` is ``violation`` or ``unknown``."""
    if view is None:
        if not path_error:
            return None
        return f"No path: {path_error}. Clearance to the landmarks is unknown.", "unknown"
    message = plan_violation(view.result)
    if message is None:
        return None
    binding = binding_index(view.result)
    who = "" if binding is None else f" ({view.result.landmarks[binding].name!r} is marked)"
    stop = view.curves.stop_depth_mm
    return (
        f"Unsafe plan{who}: {message}. The drill stops at {stop:.2f} mm; move the target "
        "to plan a safe path.",
        "violation",
    )


class Banner(QLabel):
    """One line (wrapped) in red or amber above the views; hidden when all is well."""

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__("")
        self.ctx = ctx
        self.kind = ""
        self.setWordWrap(True)
        self.hide()
        ctx.doc.path_changed.connect(self._path)
        ctx.doc.live.path_changed.connect(self._live_path)
        ctx.doc.plan_changed.connect(lambda plan: self.show_banner(None) if plan is None else None)

    def _path(self, view: PathView | None) -> None:
        doc = self.ctx.doc
        if view is None and not doc.path_error:
            return  # a plan edit: the banner holds until the new result
        self.show_banner(banner_text(view, doc.path_error))

    def _live_path(self, view: PathView | None) -> None:
        live = self.ctx.doc.live
        if view is not None or live.error:
            self.show_banner(banner_text(view, live.error))

    def show_banner(self, content: tuple[str, str] | None) -> None:
        """Show ``(text, kind)`` or hide the banner (the style set only when the kind
        changes: restyling costs more than the text, and a drag updates it often)."""
        kind = "" if content is None else content[1]
        if content is None:
            self.kind = kind
            self.hide()
            return
        if self.text() != content[0]:
            self.setText(content[0])
        if kind != self.kind or not self.styleSheet():
            self.setStyleSheet(VIOLATION_STYLE if kind == "violation" else UNKNOWN_STYLE)
        self.kind = kind
        self.show()
