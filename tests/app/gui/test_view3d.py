"""The window's 3D view: the bone surface arrives in pieces (a coarse one first, then the finer
one the measured frame affords), the camera looks at the target from outside, and real heads
are drawn whole."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui import compute
from ctdrill.app.gui import view3d as view3d_module
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.surface import piece_count
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS

pytestmark = pytest.mark.gui

PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"
GE_TILT = "dcmqa_ct_GE_head_gantrytilt_varspacing"


def _open_and_settle(qtbot: QtBot, window: MainWindow, folder: Path) -> None:
    with qtbot.waitSignal(window.view3d.surface_settled, timeout=4 * LOAD_TIMEOUT_MS):
        window.open_folder(folder)


def _bone_cells(window: MainWindow) -> list[int]:
    return [
        int(actor.GetMapper().GetInput().GetNumberOfCells())
        for name, actor in window.view3d.actors.items()
        if name.startswith("bone:")
    ]


def _camera(window: MainWindow) -> tuple[np.ndarray, np.ndarray]:
    pos, focal, _up = window.view3d.camera_position
    return np.array(pos), np.array(focal)


def test_the_surface_is_drawn_whole_and_the_camera_looks_at_the_target_from_outside(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    window.open_plan(phantom_case.plan_path)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        _open_and_settle(qtbot, window, phantom_case.ct_dir)
    qtbot.waitUntil(lambda: window.ui_steps.pending == 0, timeout=LOAD_TIMEOUT_MS)
    view = window.view3d
    assert view.surface is not None and view.surface.n_cells > 1000
    cells = _bone_cells(window)
    assert len(cells) == piece_count(view.surface) and sum(cells) == view.surface.n_cells
    pos, focal = _camera(window)
    plan = window.doc.plan
    assert plan is not None
    np.testing.assert_allclose(focal, plan.target_lps, atol=1e-6)
    b = np.array(view.surface.bounds)
    assert not np.all((pos >= b[::2]) & (pos <= b[1::2]))  # outside the bone's box
    assert np.isfinite(view.surface_shown_s) and np.isfinite(view.settled_s)


def test_a_finer_surface_replaces_the_first_without_moving_the_camera(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase, monkeypatch: pytest.MonkeyPatch
) -> None:
    asked: list[int] = []

    def generous(n: int, _without: float, _with: float) -> int:
        asked.append(10 * n)
        return 10 * n

    monkeypatch.setattr(view3d_module, "refine_budget", generous)
    monkeypatch.setattr(compute, "FIRST_TRIANGLES", 15_000)  # the phantom's first is coarse
    window.open_plan(phantom_case.plan_path)
    first: list[int] = []
    window.view3d.surface_shown.connect(
        lambda: first.append(window.view3d.surface.n_cells) if not first else None  # type: ignore[union-attr]
    )
    _open_and_settle(qtbot, window, phantom_case.ct_dir)
    view = window.view3d
    assert view.surface is not None and len(asked) == 1
    assert first[0] <= 15_000 and asked[0] == 10 * first[0]
    # the refined surface: finer, within the budget asked, every piece of it drawn
    assert first[0] < view.surface.n_cells <= asked[0]
    assert view.surface is not window.doc.surface  # the document keeps the first one
    cells = _bone_cells(window)
    assert sum(cells) == view.surface.n_cells
    # the coarse surface's actors are gone: every piece drawn is of the refined surface
    assert len({n.split(":")[1] for n in view.actors if n.startswith("bone:")}) == 1


@pytest.mark.parametrize("series", [PHILIPS, GE_TILT])
def test_a_real_head_is_drawn_from_every_slice_and_seen_from_the_front(
    qtbot: QtBot, window: MainWindow, shared_data: Path, series: str, tmp_path: Path
) -> None:
    _open_and_settle(qtbot, window, shared_data / series)
    qtbot.waitUntil(lambda: window.ui_steps.pending == 0, timeout=LOAD_TIMEOUT_MS)
    view = window.view3d
    volume = window.doc.volume
    assert view.surface is not None and volume is not None
    assert int(view.surface.field_data["block"][2]) == 1  # thick slices: never merged
    k = volume.lps_to_index(np.asarray(view.surface.points))[:, 2]
    on_slice = np.round(k[np.abs(k - np.round(k)) < 1e-4]).astype(int)
    bone = set(np.flatnonzero((volume.hu > 300).any(axis=(1, 2))).tolist())
    drawn = set(on_slice.tolist()) & set(range(volume.hu.shape[0]))
    # no rings: every slice from the lowest to the highest drawn carries its own layer
    assert drawn == set(range(min(drawn), max(drawn) + 1))
    assert len(drawn & bone) >= 0.9 * len(bone)
    pos, focal = _camera(window)
    assert pos[1] < focal[1]  # no plan: from anterior
    window.save_screenshot(tmp_path / f"{series}.png")


def test_every_trajectory_and_implant_is_drawn_and_the_selected_one_highlighted(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    from dataclasses import replace

    from ctdrill.app.gui.scene import CLEARANCE_COLOURS
    from ctdrill.imaging.plan.implants import ImplantSpec

    window.open_plan(phantom_case.plan_path)
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        _open_and_settle(qtbot, window, phantom_case.ct_dir)
    doc = window.doc
    first = doc.plan
    assert first is not None
    spec = ImplantSpec("generic 4.1 x 10", 4.1, 10.0, 3.2, "round")
    shift = np.array([6.0, 0.0, 0.0])
    second = replace(
        first,
        name="second",
        entry_lps=first.entry_lps + shift,
        target_lps=first.target_lps + shift,
        implant=spec,
    )
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        doc.set_plans((replace(first, implant=spec), second), current=1)

    def drawn() -> bool:
        names = set(window.view3d.actors)
        return {"implant:0", "implant:1", "other:0", "drill"} <= names

    qtbot.waitUntil(drawn, timeout=LOAD_TIMEOUT_MS)
    actors = window.view3d.actors
    colour = [actors[f"implant:{i}"].GetProperty().GetColor() for i in (0, 1)]
    opacity = [actors[f"implant:{i}"].GetProperty().GetOpacity() for i in (0, 1)]
    # 6 mm between the 4.1 mm bodies' axes: 1.9 mm apart (< 3 mm), implants_too_close: both
    # drawn red (the other colours: tests/app/gui/test_problems.py); the selected one stands
    # out by its opacity
    red = CLEARANCE_COLOURS["violated"]
    assert colour[0] == pytest.approx(red, abs=1 / 255) and colour[1] == colour[0]
    assert opacity[1] > opacity[0]
    # the selected trajectory is the one drawn in full (its drill at its entry)
    b = np.array(actors["drill"].GetBounds())
    centre_x = (b[0] + b[1]) / 2.0
    assert centre_x == pytest.approx(second.entry_lps[0], abs=0.5)
    # back to the first: the highlight follows
    with qtbot.waitSignal(window.path_updated, timeout=LOAD_TIMEOUT_MS):
        doc.select(0)
    qtbot.waitUntil(
        lambda: (
            window.view3d.actors["implant:0"].GetProperty().GetOpacity()
            > window.view3d.actors["implant:1"].GetProperty().GetOpacity()
        ),
        timeout=LOAD_TIMEOUT_MS,
    )
