"""The report's curves page of a trajectory: force, HU (with the Misch bands) and clearance
against depth, the stop, the max safe depth and the planned depth marked on each.

The same figure as the export's ``force.png`` (:func:`ctdrill.app.force_figure.force_figure`:
the force axis from 0, the vibration envelope, the mean force and its 68 % band when the set
gives one), drawn by :func:`ctdrill.app.export_plot.draw_force_figure` on an A4 landscape page
with a line naming what is drawn.
"""

from __future__ import annotations

from matplotlib.figure import Figure

from ctdrill.app.export_plot import draw_force_figure
from ctdrill.app.force_figure import force_figure
from ctdrill.app.report.entries import Entry
from ctdrill.app.report.layout import LINE_SPACING, MARGIN_IN, PAGE_IN, wrap
from ctdrill.engine.stop import stop_words
from ctdrill.text import printable

#: Axes placement on the A4 page (figure fractions): room for the y labels at the left
#: (the export's figure places them 0.075 axes widths left of the axes), the title and the stop
#: label above, the x label below.
_ADJUST = {"left": 0.085, "right": 0.965, "bottom": 0.1, "top": 0.79, "hspace": 0.16}
#: The y labels' position on this wider page (axes fractions, left of the tick labels).
_YLABEL_AT = (-0.05, 0.5)


def curves_page(fig: Figure, entry: Entry) -> None:
    """Draw ``entry``'s curves on the page ``fig`` (titled by :class:`TextPages`)."""
    fig.subplots_adjust(**_ADJUST)
    ax_f, ax_h, ax_c = fig.subplots(3, 1, sharex=True)
    figure = force_figure(entry.result, entry.series, entry.band)
    draw_force_figure(fig, (ax_f, ax_h, ax_c), figure, title=False)
    for ax in (ax_f, ax_h, ax_c):
        ax.yaxis.set_label_coords(*_YLABEL_AT)
    o = entry.summary.outcome
    fig.suptitle(
        printable(f"{entry.label}: force, HU and clearance against depth"),
        fontsize=12,
        fontweight="bold",
        x=MARGIN_IN[0] / PAGE_IN[0],
        ha="left",
        y=1.0 - (MARGIN_IN[2] + 0.25) / PAGE_IN[1],
    )
    cal = o.calibration.name + (" (ILLUSTRATIVE)" if o.calibration.illustrative else "")
    note = (
        f"at {o.feed_mm_s:g} mm/s, calibration {cal}. Red line: the stop "
        f"({o.stop_depth_mm:.3f} mm, {stop_words(o.stop_reason, form='plain')}); orange dotted: "
        "the max safe depth where it is before the planned depth; grey dashed: the planned depth "
        f"({o.planned_depth_mm:.3f} mm); shaded bands behind the HU: Misch D1-D4."
    )
    y_in = MARGIN_IN[2] + 0.55
    for line in wrap(note, PAGE_IN[0] - MARGIN_IN[0] - MARGIN_IN[1], 8.5):
        fig.text(MARGIN_IN[0] / PAGE_IN[0], 1.0 - y_in / PAGE_IN[1], line, fontsize=8.5, va="top")
        y_in += 8.5 * LINE_SPACING / 72.0
