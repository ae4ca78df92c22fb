"""Depth plots painted headless into an image: what is drawn where (read back from the pixels),
the ticks, the ranges, the text's size and room."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from PySide6.QtGui import QImage, QPainter
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.plots import (
    MARGIN_PX,
    TEXT_PX,
    DepthCurves,
    PlotLayout,
    depth_limits,
    plot_layout,
)
from ctdrill.app.gui.plots_paint import paint_axes, paint_curves, paint_live_depth
from ctdrill.app.gui.screenshot import qimage_to_rgb
from tests.app.gui.plot_marks import horizontal_marks, rgb, vertical_marks_mm

#: The plots' size in the window at its default 1440 x 900 (measured: 1072 x 273 px), and in a
#: window shrunk to 1280 x 800.
SIZES = ((1072, 273), (900, 220))


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


def paint(
    c: DepthCurves | None, size: tuple[int, int] = SIZES[0], message: str = "", live: float = -1
) -> tuple[np.ndarray, PlotLayout]:
    layout = plot_layout(*size, None if c is None else depth_limits(c))
    assert layout is not None
    img = QImage(*size, QImage.Format.Format_RGB32)
    p = QPainter(img)
    paint_axes(p, layout, c, message)
    if c is not None:
        paint_curves(p, layout, c)
    if live >= 0:
        paint_live_depth(p, layout, live)
    p.end()
    return qimage_to_rgb(img), layout


def px_mm(layout: PlotLayout) -> float:
    """One pixel of depth, mm."""
    return layout.depth_at(layout.frames[0].x0 + 1.0) - layout.depth_at(layout.frames[0].x0)


def test_stop_planned_and_margin_are_painted_where_they_are(qtbot: QtBot) -> None:
    img, layout = paint(curves())
    tol = 1.5 * px_mm(layout)
    assert vertical_marks_mm(img, layout, "stop") == [[pytest.approx(7.5, abs=tol)]] * 3
    # the planned depth (dotted: a third of the height or so) beyond the stop
    for f in layout.frames:
        x = round(float(layout.x_px(10.0)))
        column = img[int(f.y0) + 2 : int(f.y1) - 1, x - 1 : x + 2]
        assert np.all(column == rgb("planned"), axis=-1).any(axis=1).mean() > 0.3
    margin = horizontal_marks(img, layout.frames[2], "margin_line")
    assert margin == [
        pytest.approx(2.5, abs=2.0 * (layout.frames[2].hi - layout.frames[2].lo) / 60)
    ]
    # the curves: the force line's colour at 5 mm sits at 3 N
    f = layout.frames[1]
    x = int(float(layout.x_px(5.0)))
    rows = np.flatnonzero(np.abs(img[:, x].astype(int) - rgb("force")).sum(axis=1) < 120)
    rows = rows[(rows > f.y0) & (rows < f.y1)]
    assert rows.size and f.value_at(float(rows.mean()) + 0.5) == pytest.approx(3.0, abs=0.3)


def test_a_stop_at_the_planned_depth_has_no_planned_mark(qtbot: QtBot) -> None:
    img, layout = paint(curves(stop=10.0, reason="planned_depth"))
    assert vertical_marks_mm(img, layout, "stop") == [[pytest.approx(10.0, abs=0.1)]] * 3
    for f in layout.frames:  # no dotted column of the planned depth's grey
        area = img[int(f.y0) + 2 : int(f.y1) - 1, int(f.x0) + 2 : int(f.x1) - 1]
        assert np.all(area == rgb("planned"), axis=-1).mean(axis=0).max() < 0.2


def test_live_cursor(qtbot: QtBot) -> None:
    img, layout = paint(curves(), live=4.0)
    tol = 1.5 * px_mm(layout)
    assert vertical_marks_mm(img, layout, "live") == [[pytest.approx(4.0, abs=tol)]] * 3


def test_empty_plots_show_the_message(qtbot: QtBot) -> None:
    blank, layout = paint(None, message="")
    for message in ("open a DICOM folder", "no force profile: " + "x " * 100):
        img, _ = paint(None, message=message)
        f = layout.frames[1]
        changed = np.any(img != blank, axis=-1)
        rows = np.flatnonzero(changed[int(f.y0) + 1 : int(f.y1)].any(axis=1))
        assert rows.size >= TEXT_PX - 3  # a line of text at least
        if len(message) > 100:  # wrapped: two lines of text
            assert rows[-1] - rows[0] > 1.5 * TEXT_PX
        assert not changed[: int(f.y0)].any() and not changed[int(f.y1) + 1 :].any()


def test_every_text_fits_the_widget_and_is_10_px(qtbot: QtBot) -> None:
    assert TEXT_PX >= 10
    base = replace(curves(), mean_lo_n=curves().force_n * 0.6, mean_hi_n=curves().force_n * 1.6)
    for size in SIZES:
        img, layout = paint(base, size)
        white = np.all(img == 255, axis=-1)
        # nothing cut at the widget's edges: the outermost pixels stay white
        assert white[:, 0].all() and white[:, -1].all() and white[-1, :].all() and white[0].all()
        # the tick labels and axis labels are painted in the margins
        left = ~white[:, : int(MARGIN_PX["left"]) - 4]
        assert left.any(axis=0).sum() > 20
        assert (~white[int(layout.frames[2].y1) + 6 :, :]).any(axis=1).sum() >= 2 * TEXT_PX - 6


def test_the_force_axis_starts_at_zero_so_a_flat_curve_looks_flat() -> None:
    d = np.linspace(0.0, 10.0, 201)
    flat = replace(curves(), force_n=5.0 + 0.05 * np.sin(d), force_band_n=None)
    lo, hi = depth_limits(flat).force
    assert lo == 0.0
    # the ripple spans at most 2.2 % of the axis (it spanned all of it when zoomed)
    assert 0.1 / (hi - lo) < 0.022 and hi >= 5.05
    neg = replace(flat, force_band_n=np.full_like(d, 6.0))  # a band below 0: shown whole
    lo, hi = depth_limits(neg).force
    assert lo == np.min(neg.force_n - 6.0) and hi > np.max(neg.force_n + 6.0)


def test_nan_gaps_break_the_curves(qtbot: QtBot) -> None:
    c = curves()
    hu = c.hu.copy()
    hu[80:120] = np.nan  # 4-6 mm: outside the volume
    img, layout = paint(replace(c, hu=hu))
    f = layout.frames[0]
    x = int(float(layout.x_px(5.0)))
    column = img[int(f.y0) + 1 : int(f.y1), x].astype(int)
    assert not (np.abs(column - rgb("hu")).sum(axis=1) < 120).any()
    x = int(float(layout.x_px(3.0)))
    column = img[int(f.y0) + 1 : int(f.y1), x].astype(int)
    assert (np.abs(column - rgb("hu")).sum(axis=1) < 120).any()


def test_the_force_title_says_the_mean_band_or_its_absence() -> None:
    from ctdrill.app.gui.plots import force_title

    base = curves()
    shown = replace(base, band_note="blue: 68 % band of the mean (calibration)")
    assert "68 % band" in force_title(shown) and "bone-illustrative" in force_title(shown)
    absent = replace(base, band_note="no uncertainty band: x gives no covariance")
    assert "no uncertainty band" in force_title(absent)
