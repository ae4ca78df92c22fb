"""Paging positions, orientation letters, the window drag and the arch edits, headless."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.app.gui.slice_nav import (
    MIN_WIDTH_HU,
    direction_letters,
    dragged_window,
    orientation_letters,
    plane_center,
    slice_stack,
    view_letters,
    window_text,
)
from ctdrill.app.gui.slice_tools import edit_arch, insert_index
from ctdrill.app.gui.slices import reslice
from tests.app.gui.test_irregular_slices import POSITIONS, _volume


def test_an_irregular_stack_pages_through_its_true_slices_and_shows_each_exactly() -> None:
    vol = _volume()  # slices at z = 0, 1, 2, 3, 10, 11, 12
    st = slice_stack(vol, "axial")
    assert st.real and st.label == "slice"
    np.testing.assert_array_equal(st.positions_mm, POSITIONS)
    z = st.step(3.0, 1)
    assert z == 10.0 and st.step(z, -1) == 3.0 and st.step(6.5, 1) == 10.0
    assert st.step(6.5, -1) == 3.0 and st.step(12.0, 5) == 12.0 and st.step(0.0, -5) == 0.0
    assert st.describe(10.0) == "z 10.00 mm · slice 5/7"
    assert st.describe(6.5) == "z 6.50 mm · between slices 4 and 5"
    for k, pos in enumerate(POSITIONS):
        img = reslice(vol, "axial", plane_center(np.zeros(3), "axial", float(pos)))
        np.testing.assert_array_equal(img.hu, vol.hu[k])  # the slice itself, no blending
    # the columns and rows of this axis-aligned stack are the other views' planes
    assert slice_stack(vol, "sagittal").label == "column"
    assert slice_stack(vol, "coronal").label == "row"


def test_a_reversed_stack_is_paged_in_increasing_coordinates() -> None:
    vol = _volume()
    flipped = type(vol)(
        hu=vol.hu[::-1].copy(),
        affine_lps=np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1.0, 12.0], [0, 0, 0, 1]]),
        valid=None,
        info=vol.info,
        slice_positions_mm=POSITIONS[::-1].copy(),  # z along the normal (x cross y = +z)
    )
    st = slice_stack(flipped, "axial")
    assert np.all(np.diff(st.positions_mm) > 0)
    np.testing.assert_allclose(st.positions_mm, POSITIONS)
    assert list(st.indices) == [6, 5, 4, 3, 2, 1, 0]  # slice 7 (index 6) is the lowest
    assert st.describe(0.0) == "z 0.00 mm · slice 7/7"


def test_orientation_letters_of_the_views() -> None:
    assert view_letters("axial") == {"left": "R", "right": "L", "top": "A", "bottom": "P"}
    assert view_letters("coronal") == {"left": "R", "right": "L", "top": "S", "bottom": "I"}
    assert view_letters("sagittal") == {"left": "A", "right": "P", "top": "S", "bottom": "I"}
    assert direction_letters(np.array([0.0, -1.0, -0.5])) == "AI"
    assert direction_letters(np.array([0.1, -1.0, -0.2])) == "A"
    u, v = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    assert orientation_letters(u, v) == {"right": "S", "left": "I", "bottom": "L", "top": "R"}


def test_the_window_drag_and_its_readout() -> None:
    assert dragged_window(500.0, 2000.0, 50.0, 20.0) == (580.0, 2200.0)
    assert dragged_window(500.0, 2000.0, -1000.0, 0.0) == (500.0, MIN_WIDTH_HU)
    assert window_text(580.0, 2200.0) == "W 2200 L 580"


def test_arch_edits() -> None:
    a = edit_arch(None, "add", 0, np.array([0.0, 0.0, 5.0]))
    a = edit_arch(a, "add", 1, np.array([10.0, 0.0, 5.0]))
    a = edit_arch(a, "add", 1, np.array([5.0, 3.0, 5.0]))  # inserted between
    np.testing.assert_array_equal(a[:, 0], [0.0, 5.0, 10.0])
    a = edit_arch(a, "move", 2, np.array([12.0, 1.0, 5.0]))
    np.testing.assert_array_equal(a[2], [12.0, 1.0, 5.0])
    assert len(edit_arch(a, "delete", 0, None)) == 2
    with pytest.raises(ValueError, match="same place"):
        edit_arch(a, "add", 1, np.array([0.0, 0.0, 5.0]))
    with pytest.raises(ValueError, match="not possible"):
        edit_arch(a, "delete", 3, None)
    px = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0]])
    assert insert_index(px, np.array([50.0, 4.0]), 10.0) == 1
    assert insert_index(px, np.array([96.0, 50.0]), 10.0) == 2
    assert insert_index(px, np.array([50.0, 50.0]), 10.0) == 3  # near no segment: appended
