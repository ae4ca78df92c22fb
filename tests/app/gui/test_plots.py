"""Depth plots drawn headless on a matplotlib Figure: what is drawn where."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ctdrill.app.gui.plots import (
    LIVE_GID,
    DepthCurves,
    draw_depth_plots,
    set_live_depth,
)


def curves(stop: float = 7.5, reason: str = "margin") -> DepthCurves:
    d = np.linspace(0.0, 10.0, 201)
    return DepthCurves(
        depth_mm=d,
        hu=np.where(d < 2.0, 1500.0, 700.0),
        force_n=np.where(d < 2.0, 9.0, 3.0),
        force_band_n=np.full_like(d, 0.5),
        clearance_mm=10.0 - d,
        planned_depth_mm=10.0,
        stop_depth_mm=stop,
        stop_reason=reason,
        margin_mm=2.5,
        calibration="bone-illustrative",
    )


def vlines(ax: object, colour: str) -> list[float]:
    out = []
    for line in ax.lines:  # type: ignore[attr-defined]
        x = np.asarray(line.get_xdata(), dtype=float)
        visible = line.get_visible()
        if visible and line.get_color() == colour and x.size == 2 and x[0] == x[1]:
            out.append(float(x[0]))
    return out


def test_three_axes_with_stop_planned_and_margin() -> None:
    fig = Figure()
    draw_depth_plots(fig, curves())
    ax_hu, ax_f, ax_c = fig.axes
    for ax in fig.axes:
        assert vlines(ax, "#d02080") == [7.5]
        assert vlines(ax, "#808080") == [10.0]
    margin = [ln for ln in ax_c.lines if ln.get_color() == "#d02020"]
    assert np.allclose(margin[0].get_ydata(), 2.5)
    assert len(ax_hu.patches) >= 5  # the five Misch bands
    assert "7.50 mm (margin)" in ax_hu.get_title(loc="left")
    assert "bone-illustrative" in ax_f.get_title(loc="left")
    assert np.array_equal(ax_f.lines[0].get_ydata(), curves().force_n)


def test_redraw_reuses_the_axes_and_replaces_the_data() -> None:
    fig = Figure()
    draw_depth_plots(fig, curves())
    axes = list(fig.axes)
    draw_depth_plots(fig, curves(stop=10.0, reason="planned_depth"))
    assert list(fig.axes) == axes
    assert all(vlines(ax, "#d02080") == [10.0] for ax in fig.axes)
    assert all(vlines(ax, "#808080") == [] for ax in fig.axes)  # nothing beyond the stop


def test_live_cursor_moves_and_goes() -> None:
    fig = Figure()
    draw_depth_plots(fig, curves())
    set_live_depth(fig, 3.0)
    set_live_depth(fig, 4.0)
    for ax in fig.axes:
        live = [ln for ln in ax.lines if ln.get_gid() == LIVE_GID]
        assert len(live) == 1 and list(live[0].get_xdata()) == [4.0, 4.0]
    set_live_depth(fig, None)
    assert not any(ln.get_gid() == LIVE_GID for ax in fig.axes for ln in ax.lines)


def test_empty_plots_show_the_message() -> None:
    fig = Figure()
    draw_depth_plots(fig, None, message="open a DICOM folder")
    assert any(t.get_text() == "open a DICOM folder" for t in fig.axes[1].texts)
    draw_depth_plots(fig, None, message="no force profile: " + "x " * 100)
    (text,) = fig.axes[1].texts
    assert text.get_text().count("\n") == 1  # long messages are wrapped


def test_the_mean_force_band_is_drawn_or_its_absence_said() -> None:
    from dataclasses import replace

    base = curves()
    with_band = replace(
        base,
        mean_lo_n=base.force_n * 0.6,
        mean_hi_n=base.force_n * 1.6,
        band_note="blue: 68 % band of the mean (calibration)",
    )
    fig = Figure()
    draw_depth_plots(fig, with_band)
    ax_f = fig.axes[1]
    edges = [ln for ln in ax_f.lines if ln.get_color() == "#4060c0"]
    assert len(edges) == 2
    assert np.allclose(edges[0].get_ydata(), base.force_n * 0.6)
    assert np.allclose(edges[1].get_ydata(), base.force_n * 1.6)
    assert "68 % band" in ax_f.get_title(loc="left")
    draw_depth_plots(fig, replace(base, band_note="no uncertainty band: x gives no covariance"))
    assert not [ln for ln in fig.axes[1].lines if ln.get_color() == "#4060c0"]
    assert "no uncertainty band" in fig.axes[1].get_title(loc="left")


def _window_figure() -> Figure:
    """The plots at the size the window gives them at its default 1440 x 900 (measured on a
    screenshot: about 1070 x 290 px) and its resolution."""
    from ctdrill.app.gui.plots import WINDOW_DPI

    return Figure(figsize=(1070 / WINDOW_DPI, 290 / WINDOW_DPI), dpi=WINDOW_DPI)


def test_every_text_is_at_least_10_px_and_inside_the_figure() -> None:
    from dataclasses import replace

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from ctdrill.app.gui.plots import WINDOW_DPI

    for small in (False, True):
        fig = _window_figure()
        if small:  # a window shrunk to 1280 x 800: the labels keep their room
            fig.set_size_inches(900 / WINDOW_DPI, 220 / WINDOW_DPI)
        canvas = FigureCanvasAgg(fig)
        draw_depth_plots(fig, replace(curves(), calibration="bone-illustrative"))
        canvas.draw()
        renderer = canvas.get_renderer()
        box = fig.bbox
        hidden = set()  # tick labels of ticks outside the view are not drawn
        for ax in fig.axes:
            x0, x1 = sorted(ax.get_xlim())
            y0, y1 = sorted(ax.get_ylim())
            hidden |= {id(t) for t in ax.get_xticklabels() if not x0 <= t.get_position()[0] <= x1}
            hidden |= {id(t) for t in ax.get_yticklabels() if not y0 <= t.get_position()[1] <= y1}
        texts = [
            t
            for t in fig.findobj(lambda a: hasattr(a, "get_fontsize"))
            if t.get_text() and t.get_visible() and id(t) not in hidden
        ]
        assert len(texts) > 15  # tick labels, axis labels, titles, Misch names, margin
        for t in texts:
            assert t.get_fontsize() * WINDOW_DPI / 72.0 >= 10.0 - 1e-9, t.get_text()
            ext = t.get_window_extent(renderer)
            assert ext.x0 >= box.x0 - 0.5 and ext.x1 <= box.x1 + 0.5, t.get_text()
            assert ext.y0 >= box.y0 - 0.5 and ext.y1 <= box.y1 + 0.5, t.get_text()


def test_the_force_axis_starts_at_zero_so_a_flat_curve_looks_flat() -> None:
    from dataclasses import replace

    d = np.linspace(0.0, 10.0, 201)
    flat = replace(
        curves(),
        force_n=5.0 + 0.05 * np.sin(d),  # 4.95 .. 5.05 N: a ripple of 2 %
        force_band_n=None,
    )
    fig = _window_figure()
    draw_depth_plots(fig, flat)
    lo, hi = fig.axes[1].get_ylim()
    assert lo == 0.0
    # the ripple spans at most 2.2 % of the axis (it spanned all of it when zoomed)
    assert 0.1 / (hi - lo) < 0.022 and hi >= 5.05
    # a band reaching below 0 is shown whole
    neg = replace(flat, force_band_n=np.full_like(d, 6.0))
    draw_depth_plots(fig, neg)
    lo, hi = fig.axes[1].get_ylim()
    assert lo == np.min(neg.force_n - 6.0) and hi > np.max(neg.force_n + 6.0)
