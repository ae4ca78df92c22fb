"""The banner over the views: every plan problem of the current trajectory
(:mod:`ctdrill.app.gui.problems`: drill margin, implant margin, thin wall, perforation,
implants too close, implant above the entry; each with its warning code and the outputs'
message), or why no path could be computed (clearance unknown), and a series whose voxels are
too coarse for the clearances (``coarse_voxels``); while a trajectory is dragged it follows the
dragged plan's path **without changing its height** (the views under the cursor must not move:
it keeps the height it had when the drag started, its text cut to it, first line first, and a
banner hidden then stays hidden until the release).

The banner has **a fixed height** (:data:`BANNER_PX`, about three lines): its first line counts
the problems, the list under it scrolls, so five problems never shrink the views under it."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QFrame, QLabel, QScrollArea

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.problems import plan_problems, problems_text
from ctdrill.app.gui.results import PathView
from ctdrill.imaging import CTVolume
from ctdrill.imaging.resolution import clearance_decimals, volume_clearance_accuracy_mm

VIOLATION_STYLE = "background:#c62828; color:white; font-weight:bold; padding:6px"
UNKNOWN_STYLE = "background:#8d6e00; color:white; font-weight:bold; padding:6px"
CLEAR_STYLE = "background:#2e7d32; color:white; font-weight:bold; padding:6px"
#: What a banner shown when a drag started says where the dragged plan has no problem.
CLEAR_TEXT = "No plan problem at this position."
#: Qt's largest widget height (QWIDGETSIZE_MAX).
MAX_HEIGHT_PX = 16_777_215
#: The banner's fixed height, px: the count line and about two problems; the rest scrolls.
BANNER_PX = 72


def coarse_note(volume: CTVolume | None) -> str:
    """The series' ``coarse_voxels`` warning in one line ("" when fine): what it limits the
    clearances to (the whole warning is in the Series tab and the banner's tooltip)."""
    if volume is None or not any(w.code == "coarse_voxels" for w in volume.warnings):
        return ""
    acc = volume_clearance_accuracy_mm(volume)
    step = 10.0 ** -clearance_decimals(acc)
    return (
        f"Coarse voxels (coarse_voxels): clearances and walls on this series are known only to "
        f"about +-{acc:.2g} mm (shown to {step:g} mm); the Series tab says why."
    )


def coarse_tooltip(volume: CTVolume | None) -> str:
    """The whole ``coarse_voxels`` warning ("" when fine)."""
    found = [] if volume is None else [w for w in volume.warnings if w.code == "coarse_voxels"]
    return "" if not found else f"coarse_voxels: {found[0].message}"


def marked_text(view: PathView) -> str:
    """What the views mark red: the trajectory's implant and the landmarks whose margin the
    implant or the osteotomy breaks ("" when none)."""
    names = []
    if view.plan.implant is not None:
        names.append("the implant")
    if view.planned is not None:
        broken = view.planned.broken()
        names += [repr(lm.name) for lm, b in zip(view.result.landmarks, broken, strict=True) if b]
    if not names:
        return ""
    verb = "is" if len(names) == 1 else "are"
    return f" ({' and '.join(names)} {verb} marked red)"


def banner_text(
    view: PathView | None, path_error: str, coarse: str = "", stop_mm: float | None = None
) -> tuple[str, str] | None:
    """(text, kind) of the banner for a path result (or its failure), None: no banner.
    ``kind`` is ``violation`` (plan problems), ``unknown`` (no path) or ``coarse`` (only the
    series' ``coarse_voxels``, the note ``coarse`` added to every banner). ``stop_mm``: the
    stop the plots show (a drag's newest curves, ahead of its checks), else the view's."""
    tail = f"\n{coarse}" if coarse else ""
    if view is None:
        if not path_error:
            return (coarse, "coarse") if coarse else None
        return f"No path: {path_error}. Clearance to the landmarks is unknown.{tail}", "unknown"
    problems = view.problems or plan_problems(view.result.warnings)
    if not problems:
        return (coarse, "coarse") if coarse else None
    n = len(problems)
    head = f"Unsafe plan {view.plan.name!r}{marked_text(view)}: {n} problem{'s' * (n > 1)}."
    if any(w.code == "plan_violates_margin" for w in problems):
        head += (
            f" The drill stops at {view.curves.stop_depth_mm if stop_mm is None else stop_mm:.2f}"
            " mm; move the target to plan a "
            "safe path."
        )
    return f"{head}\n{problems_text(problems)}{tail}", "violation"


class Banner(QScrollArea):
    """Lines (wrapped) in red or amber above the views, a fixed height with the list
    scrolling; hidden when all is well."""

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.kind = ""
        #: The height kept while a drag runs (0: hidden when it started), None: no drag.
        self.frozen_px: int | None = None
        self.label = QLabel("")
        self.label.setObjectName("banner:text")
        self.label.setWordWrap(True)
        self.label.setAlignment(Qt.AlignmentFlag.AlignTop | Qt.AlignmentFlag.AlignLeft)
        self.setWidget(self.label)
        self.setWidgetResizable(True)
        self.setFrameShape(QFrame.Shape.NoFrame)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setFixedHeight(BANNER_PX)
        self.hide()
        ctx.doc.path_changed.connect(self._path)
        ctx.doc.live.path_changed.connect(self._live_path)
        ctx.doc.plan_changed.connect(self._plan)
        ctx.doc.volume_changed.connect(lambda _v: self._plan(ctx.doc.plan))
        ctx.doc.live.plan_dragged.connect(self._dragged)
        ctx.doc.live.curves_changed.connect(lambda _view: self._live_path(ctx.doc.live.path))

    def text(self) -> str:
        """The banner's text (count line, then the problems)."""
        return self.label.text()

    def _dragged(self, plan: object) -> None:
        """A drag starts (keep the height) or ends (free it)."""
        if plan is None:
            self.frozen_px = None
            self.setFixedHeight(BANNER_PX)
        elif self.frozen_px is None:
            self.frozen_px = self.height() if self.isVisible() else 0
            if self.frozen_px:
                self.setFixedHeight(self.frozen_px)

    def _coarse(self) -> str:
        volume = self.ctx.doc.volume
        tip = coarse_tooltip(volume)
        if self.toolTip() != tip:  # a drag asks on every move: no event for the same tip
            self.setToolTip(tip)
        return coarse_note(volume)

    def _plan(self, plan: object) -> None:
        if plan is None or self.kind in ("", "coarse"):
            self.show_banner(banner_text(None, "", self._coarse()))

    def _path(self, view: PathView | None) -> None:
        doc = self.ctx.doc
        if view is None and not doc.path_error:
            return  # a plan edit: the banner holds until the new result
        self.show_banner(banner_text(view, doc.path_error, self._coarse()))

    def _live_path(self, view: PathView | None) -> None:
        live = self.ctx.doc.live
        if self.frozen_px == 0:
            return  # hidden when the drag started: showing it would move the views
        if view is not None or live.error:
            drawn = None if live.curves is None else live.curves.curves.stop_depth_mm
            content = banner_text(view, live.error, self._coarse(), drawn)
            if content is None and self.frozen_px:
                content = CLEAR_TEXT, "clear"
            self.show_banner(content)

    def show_banner(self, content: tuple[str, str] | None) -> None:
        """Show ``(text, kind)`` or hide the banner (the style set only when the kind
        changes: restyling costs more than the text, and a drag updates it often)."""
        kind = "" if content is None else content[1]
        if content is None:
            self.kind = kind
            self.hide()
            return
        if self.text() != content[0]:
            self.label.setText(content[0])
        if kind != self.kind or not self.label.styleSheet():
            styles = {"violation": VIOLATION_STYLE, "clear": CLEAR_STYLE}
            self.label.setStyleSheet(styles.get(kind, UNKNOWN_STYLE))
        self.kind = kind
        self.show()
