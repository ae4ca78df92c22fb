"""A plan edit's landmark meshes are made on the 3D view's render thread while its path is
planned, and found again (the same objects) when the path result's scene is built there."""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui import meshes
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.meshes import LANDMARK_MESHES_KEPT, landmark_meshes
from ctdrill.app.gui.planning import landmark_geometries
from ctdrill.app.gui.scene import LandmarkGeometry
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import open_case

CANAL = np.array([[-20.0, 0.0, -4.0], [0.0, 1.0, -4.5], [20.0, 0.0, -4.0]])


def test_equal_geometry_gives_the_kept_meshes_and_a_new_one_new_meshes() -> None:
    lm = LandmarkGeometry("canal", CANAL, 1.2, 2.0, 1.0)
    body, env = landmark_meshes(lm)
    # the same geometry from equal arrays, another clearance: the same meshes
    again = landmark_meshes(LandmarkGeometry("canal", CANAL.copy(), 1.2, 2.0, None))
    assert again[0] is body and again[1] is env
    moved = CANAL.copy()
    moved[1, 2] += 0.5
    other = landmark_meshes(LandmarkGeometry("canal", moved, 1.2, 2.0, 1.0))
    assert other[0] is not body
    assert not np.allclose(np.asarray(other[0].points).mean(0), np.asarray(body.points).mean(0))
    wider = landmark_meshes(LandmarkGeometry("canal", CANAL, 1.2, 2.5, 1.0))
    assert wider[0] is not body  # the margin is part of what is kept
    # a bounded number kept
    for k in range(LANDMARK_MESHES_KEPT + 2):
        landmark_meshes(LandmarkGeometry("canal", CANAL + k + 10.0, 1.2, 2.0, 1.0))
    assert len(meshes._kept.meshes) == LANDMARK_MESHES_KEPT
    assert landmark_meshes(lm)[0] is not body  # pushed out: made again
    # each thread keeps its own (a mesh is never shared between render windows' threads)
    theirs: list[object] = []
    worker = threading.Thread(target=lambda: theirs.append(landmark_meshes(lm)[0]))
    worker.start()
    worker.join(30)
    assert theirs and theirs[0] is not landmark_meshes(lm)[0]


@pytest.mark.gui
def test_a_plan_edit_has_its_canal_meshes_made_on_the_render_thread(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    plan = window.plan
    assert plan is not None and plan.landmarks
    canal = plan.landmarks[0]
    moved = replace(canal, points_lps=np.asarray(canal.points_lps) + np.array([0.0, 0.0, 0.3]))
    edited = replace(plan, landmarks=(moved, *plan.landmarks[1:]))
    view = window.view3d
    view.prefetch(edited)
    lm = landmark_geometries(edited)[0]
    ready = view.rt.call(lambda _stage: dict(getattr(meshes._kept, "meshes", {})))
    made = view.rt.call(lambda _stage: landmark_meshes(lm))
    assert any(m is made for m in ready.values())  # made by the prefetch, found again
