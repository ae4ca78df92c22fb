"""force.png drawn lean: the envelope, the PNG encoder and the reused figure (issue 17)."""

from __future__ import annotations

import io
import zlib
from dataclasses import replace

import numpy as np
from PIL import Image

import ctdrill.app.export_plot as plot
from ctdrill.app.export_plot import envelope, force_png, png_bytes
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


def test_reused_figure_leaves_nothing_behind() -> None:
    """The figure is built once per process: a plot drawn after another trajectory's (with
    other landmarks, limits and legend) is the same image as on a fresh figure."""
    a, sa, b, sb = _demo()
    plot._CANVAS = None
    first = io.BytesIO()
    force_png(a, sa, first)
    other = io.BytesIO()
    force_png(b, sb, other)
    again = io.BytesIO()
    force_png(a, sa, again)
    assert first.getvalue() == again.getvalue()
    assert first.getvalue() != other.getvalue()
    plot._CANVAS = None
    fresh = io.BytesIO()
    force_png(b, sb, fresh)
    assert fresh.getvalue() == other.getvalue()
    with Image.open(io.BytesIO(first.getvalue())) as im:
        assert im.size == (1200, 1000)
        px = np.asarray(im.convert("RGB")).astype(int)
    # the force band is drawn: the default blue (#1f77b4) covers a solid area
    blue = np.all(np.abs(px - [0x1F, 0x77, 0xB4]) < 8, axis=2)
    assert blue.sum() > 10_000


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
    c = plot._canvas()
    with c.lock:
        try:
            plot._draw(c, result, series, None)
            lo, hi = c.ax_f.get_ylim()
        finally:
            c.reset()
    inside = series.force_n[series.depth_mm > 1.0]  # the lip fully in the bone
    assert lo == 0.0
    assert hi >= float(series.force_n.max())
    # the curve's own swing is a small part of the axis (it filled the axis when zoomed)
    assert (float(inside.max()) - float(inside.min())) / (hi - lo) < 0.25
    assert c.ax_f.get_autoscaley_on()  # reset hands the next trajectory an autoscaled axis
