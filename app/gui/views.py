"""Every view of the window, in one place.

A view is a widget built from a :class:`~ctdrill.app.gui.document.ViewContext`; it subscribes to
the document's signals itself and changes the document only through its methods. The window
places each view by its ``area``: ``banner`` (a strip over the rest), ``main`` (side by side,
left to right), ``page`` (a page of its own, a tab beside the main views), ``bottom`` (under
the main views) or ``tab`` (the side panel). A new view (a
panoramic reformat, say) is one new module and one line in :data:`VIEWS`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from PySide6.QtWidgets import QWidget

from ctdrill.app.gui.banner import Banner
from ctdrill.app.gui.debrief_view import DebriefView
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.panorama_view import PanoramaView
from ctdrill.app.gui.plan_panel import PlanPanel
from ctdrill.app.gui.plots_view import PlotsView
from ctdrill.app.gui.rehearsal_panel import RehearsalPanel
from ctdrill.app.gui.series_panel import SeriesPanel
from ctdrill.app.gui.slice_grid import SliceGrid
from ctdrill.app.gui.suggest_panel import SuggestPanel
from ctdrill.app.gui.teleop_view import TeleopView
from ctdrill.app.gui.view3d import View3D

Area = Literal["banner", "main", "page", "bottom", "tab"]


@dataclass(frozen=True)
class ViewSpec:
    """A view: its key, where it goes, its title (tabs) and how to build it."""

    key: str
    area: Area
    title: str
    build: Callable[[ViewContext], QWidget]


#: The window's views, in layout order within each area.
VIEWS: tuple[ViewSpec, ...] = (
    ViewSpec("banner", "banner", "", Banner),
    ViewSpec("3d", "main", "3D", View3D),
    ViewSpec("slices", "main", "Slices", SliceGrid),
    ViewSpec("panorama", "page", "Panorama and cross-section", PanoramaView),
    ViewSpec("debrief", "page", "Debrief", DebriefView),
    ViewSpec("teleop", "page", "Teleoperation", TeleopView),
    ViewSpec("plots", "bottom", "Plots", PlotsView),
    ViewSpec("plan", "tab", "Plan", PlanPanel),
    ViewSpec("suggest", "tab", "Suggest", SuggestPanel),
    ViewSpec("rehearsal", "tab", "Rehearsal", RehearsalPanel),
    ViewSpec("series", "tab", "Series", SeriesPanel),
)


def build_views(ctx: ViewContext) -> dict[str, QWidget]:
    """Build every view of :data:`VIEWS` on ``ctx``, by key."""
    return {spec.key: spec.build(ctx) for spec in VIEWS}
