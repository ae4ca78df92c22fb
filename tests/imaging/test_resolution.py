"""Coarse data are named (``coarse_voxels``) and clearances printed with the digits the data
support (``imaging/resolution.py``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging import load_series
from ctdrill.imaging.resolution import (
    COARSE_IN_PLANE_MM,
    COARSE_SLICE_MM,
    clearance_accuracy_mm,
    clearance_decimals,
    coarse_voxels_warning,
    format_clearance_mm,
    volume_clearance_accuracy_mm,
    volume_coarse_warning,
)
from tests.imaging.factory import affine, linear_hu, write

DEMO_CT = Path(__file__).resolve().parents[2] / "assets" / "demo" / "ct"


@pytest.mark.parametrize(
    ("in_plane", "step", "thickness", "named"),
    [
        (0.5, 1.25, 1.25, None),  # on the limits: not coarse
        (0.3, 0.3, None, None),
        (0.51, 1.0, 1.0, "in-plane spacing 0.51 mm"),
        (0.4, 1.3, 1.0, "slice step 1.3 mm"),
        (0.4, 1.0, 2.0, "slice thickness 2 mm"),  # thick slices, overlapping steps
        (0.4, None, 3.0, "slice thickness 3 mm"),  # one slice
        (0.45, 5.0, 5.0, "slice step 5 mm, slice thickness 5 mm"),
    ],
)
def test_coarse_voxels_names_the_spacing_and_the_accuracy(
    in_plane: float, step: float | None, thickness: float | None, named: str | None
) -> None:
    w = coarse_voxels_warning(in_plane, step, thickness)
    if named is None:
        assert w is None
        return
    assert w is not None and w.code == "coarse_voxels"
    assert f"coarse voxels: {named} (above {COARSE_SLICE_MM:g} mm" in w.message
    assert f"{COARSE_IN_PLANE_MM:g} mm in plane" in w.message
    acc = clearance_accuracy_mm(in_plane, step, thickness)
    assert f"+-{acc:.2g} mm" in w.message


def test_accuracy_is_half_the_coarsest_sampling() -> None:
    assert clearance_accuracy_mm(0.4, 0.4, 0.4) == pytest.approx(0.2)
    assert clearance_accuracy_mm(0.45, 5.0, 5.0) == pytest.approx(2.5)
    assert clearance_accuracy_mm(0.3, 0.5, 1.0) == pytest.approx(0.5)  # thickness blurs
    assert clearance_accuracy_mm(0.8, None, None) == pytest.approx(0.4)


@pytest.mark.parametrize(
    ("accuracy", "decimals"),
    [(2.5, 0), (1.0, 0), (0.6, 1), (0.2, 1), (0.1, 1), (0.05, 2), (0.01, 2), (1e-5, 3)],
)
def test_digits_follow_the_accuracy(accuracy: float, decimals: int) -> None:
    assert clearance_decimals(accuracy) == decimals
    # the last digit printed is the largest power of ten not above the accuracy
    assert 10.0**-decimals <= accuracy or decimals == 3


def test_format_clearance() -> None:
    assert format_clearance_mm(2.089, 0.2) == "2.1"  # 0.4 mm voxels
    assert format_clearance_mm(0.91, 2.5) == "1"  # 5 mm slices
    assert format_clearance_mm(0.914, 0.05) == "0.91"
    assert format_clearance_mm(-0.04, 0.2) == "-0.0"  # still inside: the sign stays
    assert clearance_decimals(float("nan")) == 3


def test_a_coarse_series_says_so_on_load_and_in_inspect(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write(tmp_path, linear_hu((4, 6, 7)), affine((0.4, 0.4, 2.0)), slice_thickness_mm=2.0)
    vol = load_series(tmp_path)
    assert vol.warning_codes == ("coarse_voxels",)
    assert volume_clearance_accuracy_mm(vol) == pytest.approx(1.0)
    assert main(["inspect", str(tmp_path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    (w,) = doc["warnings"]
    assert w["code"] == "coarse_voxels" and "slice step 2 mm" in w["message"]
    assert "+-1 mm" in w["message"] and "whole millimetres" in w["message"]


def test_the_demo_is_fine_enough() -> None:
    vol = load_series(DEMO_CT)
    assert volume_coarse_warning(vol) is None and "coarse_voxels" not in vol.warning_codes
    assert volume_clearance_accuracy_mm(vol) == pytest.approx(0.2, abs=1e-9)
    assert clearance_decimals(volume_clearance_accuracy_mm(vol)) == 1
    np.testing.assert_allclose(vol.spacing_mm, 0.4, atol=1e-9)
