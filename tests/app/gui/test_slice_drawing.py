"""What the slice views draw, checked against the geometry: the drill band is the drill's
diameter down to the stop, the canal's outlines lie on its tube and its margin."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.sections import polyline_distance_mm
from ctdrill.app.gui.slice_overlays import CURRENT_COLOUR, OTHER_COLOUR
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import open_case
from tests.app.gui.test_slice_navigation import settle, shots

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def _drill_patches(canvas: object) -> list[np.ndarray]:
    ax = canvas.ax  # type: ignore[attr-defined]
    out = []
    for patch in ax.patches:
        if not patch.get_fill():  # an implant outline
            continue
        edge = patch.get_edgecolor()
        if np.allclose(edge[:3], _rgb(CURRENT_COLOUR)):
            out.append(np.asarray(patch.get_xy()))
    return out


def _rgb(hex_colour: str) -> tuple[float, float, float]:
    h = hex_colour.lstrip("#")
    return tuple(int(h[i : i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]


def test_the_drill_band_and_the_canal_tube_on_the_demo(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    window.resize(1440, 900)
    open_case(qtbot, window, phantom_case)
    settle(qtbot, window)
    plan, view = window.plan, window.view
    assert plan is not None and view is not None
    stop = view.curves.stop_depth_mm
    cor = window.slice_canvases["coronal"]
    img = cor.image
    assert img is not None
    # The coronal plane holds the (vertical) drill: a band 2 r wide from the entry to the stop,
    # closed by the cone tip.
    (band,) = _drill_patches(cor)
    axis_uv, _ = img.to_plane_mm(np.array([plan.entry_lps, plan.point_at_depth_lps(stop)]))
    r = plan.drill.radius_mm
    assert band[:, 0].min() == pytest.approx(axis_uv[0, 0] - r, abs=1e-9)
    assert band[:, 0].max() == pytest.approx(axis_uv[0, 0] + r, abs=1e-9)
    along = band[:, 1] - axis_uv[0, 1]  # v grows downwards = deeper (the drill goes down)
    assert (along.min(), along.max()) == pytest.approx((0.0, stop), abs=1e-9)
    tip = band[np.argmax(along)]
    assert tip[0] == pytest.approx(axis_uv[0, 0], abs=1e-9)
    # The canal's outlines: every contour vertex lies on the tube (radius) or the margin.
    canal = plan.landmarks[0]
    radius, margin = float(canal.radius_mm), plan.landmark_margin_mm(canal)
    levels = []
    for coll in cor.ax.collections:
        if not hasattr(coll, "levels") or getattr(coll, "filled", True):
            continue
        for level, path in zip(coll.levels, coll.get_paths(), strict=True):
            if len(path.vertices):
                d = polyline_distance_mm(img.to_lps(path.vertices), canal.points_lps)
                np.testing.assert_allclose(d, level, atol=0.02)
                levels.append(float(level))
    assert sorted(levels) == pytest.approx([radius, radius + margin])
    window.grab().save(str(shots(tmp_path) / "demo_drawing.png"))


def test_every_trajectory_is_drawn_the_current_one_highlighted(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, tmp_path: Path
) -> None:
    window.resize(1440, 900)
    open_case(qtbot, window, phantom_case)
    settle(qtbot, window)
    doc, grid = window.doc, window.slice_grid
    first = window.plan
    assert first is not None
    shift = np.array([-6.0, 0.0, 1.0])  # in the coronal plane through the first target
    second = replace(
        first, entry_lps=first.entry_lps + shift, target_lps=first.target_lps + shift, name="b"
    )
    assert doc.set_plans((first, second), 0, edit="add trajectory")
    settle(qtbot, window)
    cor = window.slice_canvases["coronal"]
    filled = [p for p in cor.ax.patches if p.get_fill()]  # drills; implants are outlines
    edges = [tuple(np.round(p.get_edgecolor()[:3], 3)) for p in filled]
    assert edges.count(tuple(np.round(_rgb(CURRENT_COLOUR), 3))) == 1
    assert edges.count(tuple(np.round(_rgb(OTHER_COLOUR), 3))) == 1
    (band,) = _drill_patches(cor)
    assert cor.image is not None
    u_first = cor.image.to_plane_mm(first.entry_lps)[0][0]
    assert (band[:, 0].min() + band[:, 0].max()) / 2 == pytest.approx(u_first, abs=1e-9)
    window.grab().save(str(shots(tmp_path) / "demo_two_trajectories.png"))
    # selecting the other one highlights it and brings the planes to its target
    qtbot.keyClick(window.slice_canvases["axial"], Qt.Key.Key_PageDown)
    settle(qtbot, window)
    assert doc.select(1)
    settle(qtbot, window)
    assert grid.positions["axial"] == pytest.approx(second.target_lps[2])
    (band,) = _drill_patches(cor)
    mid = (band[:, 0].min() + band[:, 0].max()) / 2
    assert mid == pytest.approx(u_first + shift[0], abs=1e-9)
    # the handles are the current trajectory's
    np.testing.assert_array_equal(cor.scene.handles["target"], second.target_lps)
