"""The report's image pages: the panoramic reformat with every implant, a cross-section per
trajectory, and the 3D view.

The reformats are :func:`ctdrill.imaging.sampling.reformat.panorama` and
:func:`~ctdrill.imaging.sampling.reformat.cross_section`, drawn by
:func:`ctdrill.app.reformat.draw.draw_reformat` (the canal with its radius and margin zone, the
implant body, the drill to its stop, a mm scale), the same code as ``ctdrill panorama`` and the
window's views. The 3D view is :func:`ctdrill.app.gui.scene.render_offscreen` of the window's
scene, off screen. A plan without a dental arch gets a page saying so and how to add one, not a
refused report.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ctdrill.app.report.entries import Entry, drawn_entries
from ctdrill.app.report.layout import MARGIN_IN, PAGE_IN, TextPages, wrap
from ctdrill.app.report.timing import Timings
from ctdrill.engine.case import PreparedCase
from ctdrill.engine.stop import stop_words
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.text import printable

#: What the report says when the plan has no arch (and how to add one).
NO_ARCH = (
    "No dental arch in the plan, so no panoramic reformat or cross-sections perpendicular to "
    "the arch. To add one: give the plan an arch_mm polyline (points along the arch, in the "
    "plan's coordinate system; docs/plan.md), or draw it on the axial view of ctdrill gui and "
    "save the plan, or add a 3D Slicer Curve markup named 'arch' to the plan files. Then run "
    "ctdrill report again."
)
#: What a reformat page says when the reformat refuses the arch or the axis (the rest of the
#: report stands).
NOT_DRAWN = "Not drawn: {reason}. The rest of the report is unaffected."
#: The 3D view's size in pixels (about 115 per inch across the page).
VIEW3D_PX = (1200, 720)
#: A cross-section page draws its own trajectory and at most this many others: the nearest
#: whose axes come within :data:`NEIGHBOUR_MM` of its axis (the ones that can reach its thin
#: slab). The panorama draws every one. So the report's work grows with the number of
#: trajectories, not with its square (300 implants took over 150 s).
MAX_NEIGHBOURS = 8
NEIGHBOUR_MM = 15.0


def _final_entries(entries: Sequence[Entry]) -> list[Entry]:
    """One entry per trajectory: a drill sequence's final drill (its stop rules the plan)."""
    return [e for e in entries if e.drill_index is None or e.drill_index[0] == e.drill_index[1]]


def _heading(fig: Figure, title: str, note: str = "") -> float:
    """The page's heading and its wrapped note; returns where they end, inches from the top."""
    fig.text(
        MARGIN_IN[0] / PAGE_IN[0],
        1.0 - (MARGIN_IN[2] + 0.25) / PAGE_IN[1],
        printable(title),
        fontsize=12,
        fontweight="bold",
        va="top",
    )
    y = MARGIN_IN[2] + 0.55
    for line in wrap(note, PAGE_IN[0] - MARGIN_IN[0] - MARGIN_IN[1], 8.5) if note else []:
        fig.text(MARGIN_IN[0] / PAGE_IN[0], 1.0 - y / PAGE_IN[1], line, fontsize=8.5, va="top")
        y += 8.5 * 1.3 / 72.0
    return y


def _place(ax: Axes, top_in: float, *, below_in: float = 0.3, label_in: float = 0.45) -> None:
    """Fit ``ax`` between ``top_in`` (inches from the page's top) and the bottom margin, with
    room below for its tick labels and its x label's lines (``draw_reformat`` writes its
    captions there) and ``below_in`` more, ``label_in`` at the left for the y labels."""
    label = ax.get_xaxis().get_label()
    lines = label.get_text().count("\n") + 1 if label.get_text() else 0
    size_pt = float(label.get_fontsize())
    under_in = 0.3 + lines * size_pt * 1.45 / 72.0 + below_in
    left = (MARGIN_IN[0] + label_in) / PAGE_IN[0]
    bottom = (MARGIN_IN[3] + under_in) / PAGE_IN[1]
    width = 1.0 - (MARGIN_IN[0] + label_in + MARGIN_IN[1]) / PAGE_IN[0]
    height = 1.0 - (top_in + 0.15) / PAGE_IN[1] - bottom
    ax.set_position((left, bottom, width, height))


def _message(fig: Figure, title: str, message: str) -> None:
    _heading(fig, title)
    y = MARGIN_IN[2] + 0.7
    for line in wrap(message, PAGE_IN[0] - MARGIN_IN[0] - MARGIN_IN[1], 11.0):
        fig.text(MARGIN_IN[0] / PAGE_IN[0], 1.0 - y / PAGE_IN[1], line, fontsize=11, va="top")
        y += 11 * 1.35 / 72.0


def view_pages(
    pages: TextPages, case: PreparedCase, entries: Sequence[Entry], timings: Timings
) -> None:
    """Add the panoramic, the cross-sections and the 3D view to ``pages``."""
    finals = _final_entries(entries)
    arch = case.plans[0].arch_lps if case.plans else None
    t0 = time.perf_counter()
    if arch is None:
        _message(pages.figure(), "Panoramic reformat", NO_ARCH)
    else:
        fig = pages.figure()
        try:
            panorama_page(fig, case, finals, np.asarray(arch))
        except ImagingInputError as exc:  # refused before anything is drawn: say why
            _message(fig, "Panoramic reformat", NOT_DRAWN.format(reason=exc))
    timings.add("panoramic", time.perf_counter() - t0)
    t0 = time.perf_counter()
    for entry in drawn_entries(finals):
        fig = pages.figure()
        title = f"Cross-section: {entry.label}"
        if arch is None:
            _message(fig, title, NO_ARCH)
            continue
        try:
            cross_section_page(fig, case, entry, np.asarray(arch), neighbours(entry, finals))
        except ImagingInputError as exc:
            _message(fig, title, NOT_DRAWN.format(reason=exc))
    timings.add("cross-sections", time.perf_counter() - t0)
    t0 = time.perf_counter()
    view3d_page(pages.figure(), case, finals)
    timings.add("3D view", time.perf_counter() - t0)


def neighbours(entry: Entry, entries: Sequence[Entry]) -> list[Entry]:
    """``entry`` and at most :data:`MAX_NEIGHBOURS` others of ``entries``: the nearest whose
    axis (entry to target) comes within :data:`NEIGHBOUR_MM` of ``entry``'s, in order."""
    from ctdrill.imaging.plan.implant_checks import segment_distance_mm

    own = entry.result.plan
    near = []
    for k, other in enumerate(entries):
        if other is entry:
            continue
        plan = other.result.plan
        d = segment_distance_mm(own.entry_lps, own.target_lps, plan.entry_lps, plan.target_lps)
        if d <= NEIGHBOUR_MM:
            near.append((d, k))
    keep = {k for _, k in sorted(near)[:MAX_NEIGHBOURS]}
    return [e for k, e in enumerate(entries) if e is entry or k in keep]


def panorama_page(
    fig: Figure, case: PreparedCase, entries: Sequence[Entry], arch_lps: np.ndarray
) -> None:
    """The panoramic reformat along the arch with every trajectory's implant and drill."""
    from ctdrill.app.reformat.draw import draw_reformat
    from ctdrill.app.reformat.region import arch_region
    from ctdrill.imaging.sampling.reformat import panorama

    plans = [e.result.plan for e in entries]
    height, centre = arch_region(case.volume, arch_lps, plans)
    ref = panorama(case.volume, arch_lps, height_mm=height, centre_z_mm=centre)
    top = _heading(
        fig,
        "Panoramic reformat along the dental arch",
        "the curved planar reformat along the plan's arch, from its first point (left) to its "
        "last; drawn where they reach the slab: each canal with its radius and margin zone, "
        "each implant body, each drill to its stop (the caption names what lies outside).",
    )
    ax = fig.add_axes((0.1, 0.1, 0.8, 0.8))
    draw_reformat(ax, ref, plans, paths=[e.result for e in entries])
    _place(ax, top)


def cross_section_page(
    fig: Figure,
    case: PreparedCase,
    entry: Entry,
    arch_lps: np.ndarray,
    entries: Sequence[Entry],
) -> None:
    """The cross-section perpendicular to the arch through ``entry``'s drill axis, with every
    trajectory of ``entries`` that reaches its slab (a neighbouring implant shows)."""
    from ctdrill.app.reformat.draw import draw_reformat
    from ctdrill.imaging.sampling.reformat import cross_section

    plan = entry.result.plan
    o = entry.summary.outcome
    ref = cross_section(case.volume, arch_lps, axis=(plan.entry_lps, plan.target_lps))
    top = _heading(
        fig,
        f"Cross-section: {entry.label}",
        "the plane across the arch that contains the drill axis; stop at "
        f"{o.stop_depth_mm:.3f} mm ({stop_words(o.stop_reason, form='plain')}) of "
        f"{o.planned_depth_mm:.3f} mm planned.",
    )
    ax = fig.add_axes((0.1, 0.1, 0.8, 0.8))
    draw_reformat(ax, ref, [e.result.plan for e in entries], paths=[e.result for e in entries])
    _place(ax, top)


def view3d_page(fig: Figure, case: PreparedCase, entries: Sequence[Entry]) -> None:
    """The window's 3D scene rendered off screen: the bone surface, every trajectory."""
    from ctdrill.app.report.scene3d import render_case

    image = render_case(case, entries, size_px=VIEW3D_PX)
    top = _heading(
        fig,
        "3D view",
        "bone surface of the CT with every drill to its stop, implant and landmark (the "
        "window's 3D scene and starting camera, rendered off screen).",
    )
    ax = fig.add_axes((0.1, 0.1, 0.8, 0.8))
    ax.imshow(image, interpolation="antialiased")
    ax.set_axis_off()
    _place(ax, top, below_in=0.0, label_in=0.0)
