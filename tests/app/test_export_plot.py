"""force.png drawn lean: the envelope, the PNG encoder (issue 17), the figure's content decided
once and rasterised with Pillow (issue 37), its ticks against matplotlib's locator."""

from __future__ import annotations

import io
import zlib
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from PIL import Image

from ctdrill.app.export_plot import draw_force_figure, force_png, png_bytes
from ctdrill.app.force_figure import envelope, force_figure
from ctdrill.app.raster_plot import X_BINS, Y_BINS, nice_ticks
from ctdrill.engine.path import PathResult, plan_path
from ctdrill.engine.series import ForceSeries, force_time_series
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.load import load_plan
from ctdrill.model.calibration import load_calibration
from tests.conftest import ASSETS


def test_envelope_is_min_and_max_per_column() -> None:
    x = np.arange(1000) / 100.0  # 0 .. 9.99
    y = np.sin(x * 37.0)
    ex, lo, hi = envelope(x, y, 0.0, 10.0, 10)
    assert ex.shape == (10,)
    for k in range(10):
        part = y[k * 100 : (k + 1) * 100]
        assert lo[k] == part.min() and hi[k] == part.max()
        assert np.isclose(ex[k], np.mean(x[k * 100 : (k + 1) * 100]), rtol=1e-15)
    # points beyond the range fall into the end columns; an empty series is returned as is
    _, lo2, hi2 = envelope(np.array([-1.0, 0.5, 20.0]), np.array([3.0, 1.0, 2.0]), 0.0, 1.0, 2)
    assert lo2.tolist() == [3.0, 1.0] and hi2.tolist() == [3.0, 2.0]
    assert envelope(np.array([]), np.array([]), 0.0, 1.0, 5)[0].shape == (0,)


def test_png_bytes_decode_to_the_pixels() -> None:
    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, size=(37, 51, 3), dtype=np.uint8)
    rgb[5:9] = 255  # runs, and rows equal to the previous one
    data = png_bytes(rgb)
    with Image.open(io.BytesIO(data)) as im:
        assert im.mode == "RGB" and im.size == (51, 37)
        assert np.array_equal(np.asarray(im), rgb)
    # chunk CRCs are right (Pillow checks them only partly)
    pos = 8
    while pos < len(data):
        n = int.from_bytes(data[pos : pos + 4], "big")
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        assert int.from_bytes(data[pos + 8 + n : pos + 12 + n], "big") == zlib.crc32(kind + body)
        pos += 12 + n
    assert pos == len(data)


def _demo() -> tuple[PathResult, ForceSeries, PathResult, ForceSeries]:
    volume = load_series(ASSETS / "demo" / "ct")
    plan = load_plan(ASSETS / "demo" / "plan.json")
    cal = load_calibration(plan.calibration)
    a = plan_path(volume, plan, cal)
    b = plan_path(
        volume,
        replace(plan, target_lps=plan.target_lps + np.array([1.0, 0.5, 0.0]), landmarks=()),
        cal,
    )
    return (
        a,
        force_time_series(a, feed_mm_s=0.4, rate_hz=1000.0),
        b,
        force_time_series(b, feed_mm_s=0.8, rate_hz=500.0),
    )


def _png_pixels(data: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(data)) as im:
        assert im.size == (1200, 1000)
        return np.asarray(im.convert("RGB")).astype(int)


def test_the_plot_is_drawn_from_the_trajectory_alone() -> None:
    """The same trajectory gives the same bytes, before and after another one is drawn; two
    trajectories differ; the force envelope is a solid area of the default blue; nothing of
    matplotlib is imported to draw it."""
    a, sa, b, sb = _demo()
    first, other, again = io.BytesIO(), io.BytesIO(), io.BytesIO()
    force_png(a, sa, first)
    force_png(b, sb, other)
    force_png(a, sa, again)
    assert first.getvalue() == again.getvalue()
    assert first.getvalue() != other.getvalue()
    px = _png_pixels(first.getvalue())
    blue = np.all(np.abs(px - [0x1F, 0x77, 0xB4]) < 8, axis=2)
    assert blue.sum() > 10_000
    # the red stop line crosses all three panels at the stop depth's column
    red = np.all(np.abs(px - [0xD6, 0x27, 0x28]) < 40, axis=2)
    col = np.flatnonzero(red.sum(axis=0) > 250)  # the max safe depth dots over it
    assert col.size, "no vertical red line"
    left, right = 0.095 * 1200, 0.975 * 1200
    stop_px = left + a.stop_depth_mm / a.planned_depth_mm * (right - left)
    assert np.min(np.abs(col - stop_px)) <= 2.0


def test_the_png_has_text_where_the_labels_go() -> None:
    """Tick labels left of each panel, the x label below, the title above: dark pixels there
    (the renderer's layout; the text itself is looked at in docs/export.md's figure)."""
    a, sa, _, _ = _demo()
    out = io.BytesIO()
    force_png(a, sa, out)
    dark = _png_pixels(out.getvalue()).sum(axis=2) < 200
    assert dark[:60, 300:900].any()  # the title
    assert dark[960:, 450:750].any()  # "tip depth from the entry (mm)"
    assert dark[100:900, 40:100].any()  # tick labels
    assert dark[100:900, :35].any()  # the rotated axis labels


def test_the_force_axis_starts_at_zero_so_a_flat_curve_looks_flat() -> None:
    """A drill through uniform bone (the demo's D2 trabecular bone, 1050 HU, 4 to 10 mm deep):
    the force is flat with a small vibration; its axis starts at 0 N, not at the curve."""
    volume = load_series(ASSETS / "demo" / "ct")
    plan = load_plan(ASSETS / "demo" / "plan.json")
    axis = (plan.target_lps - plan.entry_lps) / plan.planned_depth_mm
    flat = replace(
        plan, entry_lps=plan.entry_lps + 4.0 * axis, target_lps=plan.entry_lps + 10.0 * axis
    )
    result = plan_path(volume, flat, load_calibration(plan.calibration))
    series = force_time_series(result, feed_mm_s=0.4, rate_hz=1000.0)
    lo, hi = force_figure(result, series, None).panels[0].ylim
    inside = series.force_n[series.depth_mm > 1.0]  # the lip fully in the bone
    assert lo == 0.0
    assert hi >= float(series.force_n.max())
    # the curve's own swing is a small part of the axis (it filled the axis when zoomed)
    assert (float(inside.max()) - float(inside.min())) / (hi - lo) < 0.25


def test_the_report_draws_the_same_figure_on_matplotlib_axes() -> None:
    """draw_force_figure puts every line, fill and limit of the figure on the axes."""
    from matplotlib.figure import Figure

    a, sa, _, _ = _demo()
    figure = force_figure(a, sa, None)
    fig = Figure()
    axes = fig.subplots(3, 1, sharex=True)
    draw_force_figure(fig, tuple(axes), figure)
    for ax, panel in zip(axes, figure.panels, strict=True):
        assert ax.get_ylim() == panel.ylim
        assert ax.get_ylabel() == panel.ylabel
        labels = [ln.get_label() for ln in ax.lines if not ln.get_label().startswith("_")]
        assert labels == [ln.label for ln in panel.lines]
        assert len(ax.collections) == len(panel.fills)
    assert axes[2].get_xlim() == figure.xlim
    assert fig.get_suptitle() == figure.title


def _mpl_ticks(lo: float, hi: float, bins: int) -> np.ndarray:
    from matplotlib.ticker import MaxNLocator

    ticks = MaxNLocator(nbins=bins, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)
    # the ticks matplotlib shows: its axis keeps a tick within 1e-10 of the range's width
    # outside the range (transforms._interval_contains_close), so 0.75 + 1 ulp on 0.625-0.75
    # is shown
    slack = 1e-10 * (hi - lo)
    return ticks[(ticks >= lo - slack) & (ticks <= hi + slack)]


@pytest.mark.parametrize(
    ("lo", "hi", "bins"),
    [(0.0, 12.6, X_BINS), (0.0, 11.8, Y_BINS), (-1100.0, 2000.0, Y_BINS), (-1.0, 13.3, Y_BINS)],
)
def test_ticks_are_matplotlibs_on_the_demo_axes(lo: float, hi: float, bins: int) -> None:
    got, _ = nice_ticks(lo, hi, bins)
    np.testing.assert_allclose(got, _mpl_ticks(lo, hi, bins), rtol=0, atol=1e-9 * (hi - lo))


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-1e4, 1e4, allow_nan=False),
    st.floats(1e-3, 1e4, allow_nan=False),
    st.integers(3, 10),
)
def test_ticks_are_nice_and_cover_the_range(lo: float, span: float, bins: int) -> None:
    """At most ``bins`` intervals of 1, 2, 2.5 or 5 times a power of ten, every tick inside
    the range, none of the step's multiples inside it left out, and labels that tell the
    ticks apart."""
    hi = lo + span
    ticks, decimals = nice_ticks(lo, hi, bins)
    assert 1 <= ticks.size <= bins + 1
    eps = 1e-9 * span + 1e-12 * abs(lo + span)
    assert ticks[0] >= lo - eps and ticks[-1] <= hi + eps
    if ticks.size > 1:
        step = float(ticks[1] - ticks[0])
        mantissa = step / 10.0 ** np.floor(np.log10(step))
        assert min(abs(mantissa - m) for m in (1.0, 2.0, 2.5, 5.0, 10.0)) < 1e-6
        assert ticks[0] - step < lo + eps and ticks[-1] + step > hi - eps
        labels = [f"{v:.{decimals}f}" for v in ticks]
        assert len(set(labels)) == len(labels)


@settings(max_examples=300, deadline=None)
@given(st.integers(-8000, 8000), st.integers(1, 80_000), st.integers(-3, 2), st.integers(3, 10))
def test_ticks_are_matplotlibs(lo_8: int, span_8: int, power: int, bins: int) -> None:
    """The same ticks as matplotlib's MaxNLocator wherever it uses no offset (a range not
    far from 0 for its width: every axis of the export figure, which starts at or below 0)."""
    lo, span = lo_8 / 8 * 10.0**power, span_8 / 8 * 10.0**power
    assume(abs(lo + span / 2) / span < 100)
    got, _ = nice_ticks(lo, lo + span, bins)
    want = _mpl_ticks(lo, lo + span, bins)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * span)
