"""render_offscreen: the window's scene and camera in an array, with no display needed."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from ctdrill.app.gui.compute import volume_surface
from ctdrill.app.gui.offscreen import render_offscreen
from ctdrill.app.gui.scene import (
    IMPLANT_COLOUR,
    ImplantGeometry,
    LandmarkGeometry,
    SceneInput,
    TrajectoryLine,
)
from ctdrill.app.gui.screenshot import region_stats
from tests.app.gui.phantom import BONE_TOP_Z, phantom_volume

ENTRY = np.array([0.0, 0.0, BONE_TOP_Z + 1.0])
TARGET = np.array([0.0, 0.0, BONE_TOP_Z - 9.0])


def _scene(implants: tuple[ImplantGeometry, ...] = ()) -> SceneInput:
    canal = LandmarkGeometry("canal", np.array([[-20.0, 0, -4], [20.0, 0, -4]]), 1.2, 2.0, 3.5)
    return SceneInput(ENTRY, TARGET, 2.0, 0.6, 9.0, (canal,), implants=implants)


def _implant(current: bool = True) -> ImplantGeometry:
    axis = (TARGET - ENTRY) / np.linalg.norm(TARGET - ENTRY)
    return ImplantGeometry(
        "4.1 x 10",
        TARGET - 10.0 * axis,
        axis,
        np.array([0.0, 9.0, 10.0]),
        np.array([2.05, 1.6, 0.0]),
        current,
    )


def _cyan(img: np.ndarray) -> int:
    """Pixels of the implant's cyan (green well above red; bone is beige, the background a
    dark grey-blue, the canal yellow, its margin green with blue below red)."""
    rgb = img.astype(int)
    return int(np.sum((rgb[..., 1] - rgb[..., 0] > 60) & (rgb[..., 2] - rgb[..., 0] > 60)))


def test_the_image_has_the_size_asked_and_shows_the_scene() -> None:
    vol = phantom_volume()
    img = render_offscreen(volume_surface(vol), _scene(), size_px=(320, 240))
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8
    assert region_stats(img).drawn
    # the orientation letters are white on the dark background (lower-left marker)
    corner = img[int(240 * 0.8) :, : int(320 * 0.2)]
    assert np.sum(np.all(corner >= 235, axis=-1)) >= 20


def test_an_implant_is_drawn_only_when_given() -> None:
    vol = phantom_volume()
    surf = volume_surface(vol)
    without = render_offscreen(surf, _scene(), size_px=(400, 300))
    with_it = render_offscreen(surf, _scene((_implant(),)), size_px=(400, 300))
    assert IMPLANT_COLOUR[1] - IMPLANT_COLOUR[0] > 0.4  # what _cyan looks for
    assert _cyan(with_it) > _cyan(without) + 300


def test_other_trajectories_are_in_view() -> None:
    vol = phantom_volume()
    far = TrajectoryLine("other", np.array([60.0, 0.0, 12.0]), np.array([60.0, 0.0, 2.0]), 2.0)
    scene = SceneInput(ENTRY, TARGET, 2.0, 0.6, others=(far,))
    img = render_offscreen(volume_surface(vol), scene, size_px=(400, 300))
    assert region_stats(img).drawn


def test_a_tiny_size_is_refused() -> None:
    with pytest.raises(ValueError, match="size_px"):
        render_offscreen(None, _scene(), size_px=(8, 8))


def test_it_renders_without_a_display_and_says_nothing() -> None:
    code = (
        "import numpy as np\n"
        "from ctdrill.app.gui.offscreen import render_offscreen\n"
        "from ctdrill.app.gui.scene import SceneInput\n"
        "s = SceneInput(np.array([0.0, 0, 10]), np.array([0.0, 0, 0]), 2.0, 0.6)\n"
        "img = render_offscreen(None, s, size_px=(64, 48))\n"
        "print(img.shape, int(img.max()))\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("(48, 64, 3)")
    assert proc.stderr == ""
