"""The Misch classes have one owner, and every boundary is where DESIGN.md section 5 puts it."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ctdrill.hu import AIR_HU
from ctdrill.imaging.misch import MISCH_BANDS_HU, MISCH_CLASSES, misch_class
from ctdrill.imaging.phantom.field import MISCH_CLASSES as PHANTOM_CLASSES

# D1 > 1250, D2 850-1250, D3 350-850, D4 150-350, D5 < 150: 1250 is not "> 1250".
BOUNDARIES = [
    (1250.0 + 1e-9, "D1"),
    (1250.0, "D2"),
    (1249.999, "D2"),
    (850.0, "D2"),
    (849.999, "D3"),
    (350.0, "D3"),
    (349.999, "D4"),
    (150.0, "D4"),
    (149.999, "D5"),
    (3071.0, "D1"),
    (-1024.0, "D5"),
]


@pytest.mark.parametrize(("hu", "label"), BOUNDARIES)
def test_every_boundary(hu: float, label: str) -> None:
    assert str(misch_class(hu)) == label


def test_arrays_keep_their_shape_and_nan_is_d5() -> None:
    hu = np.array([[1250.5, 1250.0], [np.nan, 150.0]])
    assert misch_class(hu).tolist() == [["D1", "D2"], ["D5", "D4"]]


def test_bands_tile_the_hu_axis_and_agree_with_the_classifier() -> None:
    assert tuple(b[0] for b in MISCH_BANDS_HU) == MISCH_CLASSES
    for (_, lo, _), (_, _, hi_below) in itertools.pairwise(MISCH_BANDS_HU):
        assert lo == hi_below
    for label, lo, hi in MISCH_BANDS_HU:
        inside = (max(lo, -2000.0) + min(hi, 4000.0)) / 2.0
        assert str(misch_class(inside)) == label


def test_the_phantom_classes_are_the_owners() -> None:
    assert tuple(sorted(PHANTOM_CLASSES)) == MISCH_CLASSES
    for label, (trabecular_hu, _, _) in PHANTOM_CLASSES.items():
        assert str(misch_class(trabecular_hu)) == label


def test_export_and_gui_use_the_owner() -> None:
    from ctdrill.app import export
    from ctdrill.app.gui import plots

    assert export.misch_class is misch_class
    # the GUI draws the owner's bands (open ends clipped for display)
    assert [b[0] for b in plots.MISCH_BANDS] == list(MISCH_CLASSES)
    for (_, lo, hi), (_, olo, ohi) in zip(plots.MISCH_BANDS, MISCH_BANDS_HU, strict=True):
        assert lo == max(olo, AIR_HU) and hi == min(ohi, 3000.0)


@pytest.mark.parametrize(("hu", "label"), BOUNDARIES)
def test_bone_and_cortical_agree_with_the_classes(hu: float, label: str) -> None:
    from ctdrill.imaging.misch import BONE_HU, CORTICAL_HU, is_bone, is_cortical

    assert (BONE_HU, CORTICAL_HU) == (150.0, 1250.0)
    assert bool(is_bone(hu)) == (label != "D5")
    assert bool(is_cortical(hu)) == (label == "D1")
    assert not is_bone(np.nan) and not is_cortical(np.nan)
