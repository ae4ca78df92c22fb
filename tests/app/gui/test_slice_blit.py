"""A slice view keeps its image as a background and draws a change of the overlays over it:
the pixels are matplotlib's own full draw of the same figure, and a new image, limits or size
draw the image anew."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.scene import LandmarkGeometry
from ctdrill.app.gui.slice_scene import BodyDrawing, OverlayScene, TrajectoryDrawing
from ctdrill.app.gui.slice_view import SliceCanvas
from ctdrill.app.gui.slices import SliceImage

pytestmark = pytest.mark.gui

LEVEL, WIDTH = 400.0, 2000.0


def _image(shift: float = 0.0) -> SliceImage:
    rows, cols = np.mgrid[0:120, 0:160].astype(np.float32)
    hu = 1500.0 * np.sin(rows / 9.0 + shift) * np.cos(cols / 13.0) - 200.0
    return SliceImage(
        view="axial",
        hu=hu.astype(np.float32),
        origin_lps=np.array([-20.0, -15.0, 0.0]),
        u_lps=np.array([1.0, 0.0, 0.0]),
        v_lps=np.array([0.0, 1.0, 0.0]),
        pixel_mm=0.25,
    )


def _scene(x_mm: float, *, violated: bool = False) -> OverlayScene:
    canal = np.array([[-15.0, -5.0, 0.5], [0.0, 0.0 + x_mm / 4, 0.0], [15.0, 4.0, -0.5]])
    lm = LandmarkGeometry("canal", canal, radius_mm=1.2, margin_mm=2.0, violated=violated)

    drill = BodyDrawing(
        p0_lps=np.array([x_mm, -10.0, 0.0]),
        axis_lps=np.array([0.0, 1.0, 0.0]),
        s_mm=np.array([0.0, 8.0, 9.0]),
        r_mm=np.array([1.0, 1.0, 0.0]),
    )
    tr = TrajectoryDrawing(
        name="36",
        entry_lps=np.array([x_mm, -10.0, 0.0]),
        target_lps=np.array([x_mm, 0.0, 0.0]),
        drill=drill,
        stopped=True,
        implant=None,
        current=True,
    )
    handles = {"entry": tr.entry_lps, "target": tr.target_lps}
    return OverlayScene(
        trajectories=(tr,),
        landmarks=(lm,),
        handles=handles,
        stop_lps=np.array([x_mm, -2.0, 0.0]),
        arch_lps=np.array([[-12.0, 6.0, 0.0], [0.0, 9.0, 1.0], [12.0, 6.0, 3.0]]),
    )


def _reference(canvas: SliceCanvas) -> np.ndarray:
    """matplotlib's own full draw of the canvas' figure (no kept background)."""
    FigureCanvasAgg.draw(canvas)
    return np.asarray(canvas.buffer_rgba()).copy()


def _drawn(canvas: SliceCanvas) -> np.ndarray:
    canvas.draw()
    return np.asarray(canvas.buffer_rgba()).copy()


def test_overlays_over_the_kept_image_are_matplotlibs_full_draw(qtbot: QtBot) -> None:
    canvas = SliceCanvas("axial")
    qtbot.addWidget(canvas)
    canvas.resize(420, 360)
    canvas.show()
    qtbot.waitExposed(canvas)
    events: list[object] = []
    canvas.mpl_connect("draw_event", events.append)
    canvas.show_slice(_image(), level_hu=LEVEL, width_hu=WIDTH)
    canvas.set_overlays(_scene(0.0))
    first = _drawn(canvas)
    assert (canvas.kept.full_draws, canvas.kept.blits, len(events)) == (1, 0, 1)
    np.testing.assert_array_equal(first, _reference(canvas))
    # a plan edit, then its path: the overlays alone, over the kept image, both times exact
    for x_mm, violated in ((3.0, False), (3.0, True), (-4.5, False)):
        canvas.set_overlays(_scene(x_mm, violated=violated))
        blitted = _drawn(canvas)
        np.testing.assert_array_equal(blitted, _reference(canvas))
        assert not np.array_equal(blitted, first)
    assert (canvas.kept.full_draws, canvas.kept.blits, len(events)) == (
        1,
        3,
        8,
    )  # with the references
    # a new image, a zoom, a new size: the image drawn anew (and kept again)
    canvas.show_slice(_image(0.7), level_hu=LEVEL, width_hu=WIDTH)
    np.testing.assert_array_equal(_drawn(canvas), _reference(canvas))
    canvas.zoom(1.25)
    np.testing.assert_array_equal(_drawn(canvas), _reference(canvas))
    canvas.resize(380, 300)
    qtbot.waitUntil(lambda: canvas.get_width_height() == (380, 300), timeout=5000)
    np.testing.assert_array_equal(_drawn(canvas), _reference(canvas))
    assert canvas.kept.full_draws == 4
    canvas.set_overlays(_scene(1.0))
    np.testing.assert_array_equal(_drawn(canvas), _reference(canvas))
    assert canvas.kept.full_draws == 4 and canvas.kept.blits == 4


@pytest.mark.parametrize("fmt", ["-", "--", ":", "o", "s", "x"])
def test_overlay_lines_are_what_plot_draws(fmt: str) -> None:
    from matplotlib.figure import Figure

    from ctdrill.app.gui.slice_overlays import _line

    def drawn(make: object) -> tuple[np.ndarray, str, object, object]:
        fig = Figure(figsize=(2.0, 2.0), dpi=80)
        FigureCanvasAgg(fig)
        ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
        ax.set_xlim(-1.0, 4.0)
        ax.set_ylim(4.0, -1.0)
        x, y = [0.0, 1.0, 2.5, 3.0], [0.5, 2.0, 1.0, 3.5]
        style = {"color": "#ff9040", "lw": 1.4, "ms": 6, "mew": 1.5, "alpha": 0.8, "zorder": 4}
        line = make(ax, x, y, fmt, **style)  # type: ignore[operator]
        fig.canvas.draw()
        buf = np.asarray(fig.canvas.buffer_rgba()).copy()
        return buf, line.get_label(), line.get_linestyle(), line.get_marker()

    plotted = drawn(lambda ax, x, y, f, **s: ax.plot(x, y, f, **s)[0])
    made = drawn(_line)
    np.testing.assert_array_equal(made[0], plotted[0])
    assert made[1:] == plotted[1:]
