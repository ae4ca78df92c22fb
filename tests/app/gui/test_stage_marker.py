"""The orientation cube, drawn in a window of its own and laid over the frame's corner: the same
pixels as the cube drawn as a second layer of the frame's window (as VTK's orientation widgets
draw it), and drawn again only when the camera turns or the frame's size changes."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from ctdrill.app.gui.camera import CameraPose, apply_camera, orientation_cube
from ctdrill.app.gui.stage import MARKER_SIZE, Stage, over_premultiplied


def _layered(stage: Stage) -> np.ndarray:
    """The frame with the cube drawn as a second layer of the frame's own window (the
    reference: a renderer in layer 1 over the corner, turned as the camera)."""
    from vtkmodules.vtkRenderingCore import vtkRenderer

    win = stage.window
    cam = stage.renderer.GetActiveCamera()
    layer = vtkRenderer()
    layer.SetLayer(1)
    layer.SetViewport(0.0, 0.0, MARKER_SIZE, MARKER_SIZE)
    layer.InteractiveOff()
    layer.AddViewProp(orientation_cube())
    win.SetNumberOfLayers(2)
    win.AddRenderer(layer)
    view = np.subtract(cam.GetPosition(), cam.GetFocalPoint())
    mc = layer.GetActiveCamera()
    try:
        for _ in range(2):  # the cube's bounds are its drawn ones from its second frame on
            mc.SetFocalPoint(0.0, 0.0, 0.0)
            mc.SetPosition(*(view / np.linalg.norm(view) * 5.0).tolist())
            mc.SetViewUp(*cam.GetViewUp())
            layer.ResetCamera()
            stage.renderer.ResetCameraClippingRange()
            win.Render()
        from ctdrill.app.gui.stage import _read_rgba

        return _read_rgba(win)
    finally:
        win.RemoveRenderer(layer)
        win.SetNumberOfLayers(1)


def _scene(size: tuple[int, int]) -> Stage:
    import pyvista as pv

    stage = Stage(size)
    stage.set_background((0.12, 0.14, 0.19), top=(0.27, 0.32, 0.42))
    stage.add_mesh(pv.Sphere(radius=8.0), name="ball", color=(0.9, 0.8, 0.6), opacity=0.45)
    stage.add_mesh(pv.Cube(x_length=6.0), name="box", color=(0.2, 0.7, 0.3))
    stage.set_marker(orientation_cube())
    return stage


def _pose(position: tuple[float, float, float], up: tuple[float, float, float]) -> CameraPose:
    return CameraPose(position_lps=np.array(position), focal_lps=np.zeros(3), up=np.array(up))


@pytest.mark.parametrize("size", [(300, 220), (257, 131)])
def test_the_cube_has_the_pixels_of_a_second_layer(size: tuple[int, int]) -> None:
    stage = _scene(size)
    try:
        for pose in (_pose((20.0, -60.0, 25.0), (0, 0, 1)), _pose((-50.0, 10.0, -30.0), (0, 1, 0))):
            apply_camera(stage, pose)
            stage.render()
            ours = stage.rgba()
            reference = _layered(stage)
            assert ours.shape == reference.shape == (size[1], size[0], 4)
            np.testing.assert_array_equal(ours[..., :3], reference[..., :3])
            w, h = stage.marker_size_px()
            corner = ours[size[1] - h :, :w, :3].reshape(-1, 3)
            assert len(np.unique(corner, axis=0)) > 3  # the cube is there, lettered
    finally:
        stage.close()


def test_the_cube_is_drawn_again_only_when_the_camera_turns_or_the_size_changes() -> None:
    stage = _scene((200, 150))
    try:
        drawn: list[Any] = []
        stage.render()  # the first frame draws the cube (its window made then)
        assert stage._marker_window is not None
        stage._marker_window.AddObserver("StartEvent", lambda *_: drawn.append(1))
        stage.render()
        assert drawn == []  # a scene change: the cube's image is reused
        apply_camera(stage, _pose((60.0, 5.0, 5.0), (0, 0, 1)))
        stage.render()
        assert len(drawn) == 1
        cam = stage.renderer.GetActiveCamera()
        cam.Dolly(1.5)  # closer along the same direction: the cube is unchanged
        stage.render()
        assert len(drawn) == 1
        stage.set_size((240, 150))
        stage.render()
        assert len(drawn) == 2
        assert stage._marker_rgba is not None
        assert stage._marker_rgba.shape[:2] == (30, 48)
    finally:
        stage.close()


def test_over_premultiplied() -> None:
    dst = np.full((1, 4, 4), 100, dtype=np.uint8)
    src = np.array([[[0, 0, 0, 0], [200, 10, 0, 255], [64, 32, 0, 128], [5, 5, 5, 0]]], np.uint8)
    over_premultiplied(dst, src)
    # alpha 0: unchanged; 255: the source; 128: source + 127/255 of the destination
    assert dst[0, 0, :3].tolist() == [100, 100, 100]
    assert dst[0, 1, :3].tolist() == [200, 10, 0]
    assert dst[0, 2, :3].tolist() == [114, 82, 50]
    assert dst[0, 3, :3].tolist() == [100, 100, 100]
    assert dst[..., 3].tolist() == [[100, 100, 100, 100]]
