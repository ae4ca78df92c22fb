"""Deleted slices in the real demo CT, through the CLI: exact when not crossed, refused or
interpolated on request when crossed (issue 14's reproduction)."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import pydicom
import pytest

from ctdrill.app.cli import main
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def _ct_without(tmp: Path, z_lo: float, z_hi: float) -> Path:
    """A copy of the demo CT without the slices whose z (IPP) lies in [z_lo, z_hi]."""
    out = tmp / f"ct_{z_lo:g}_{z_hi:g}"
    out.mkdir()
    dropped = 0
    for f in sorted((DEMO / "ct").iterdir()):
        z = float(pydicom.dcmread(f, stop_before_pixels=True).ImagePositionPatient[2])
        if z_lo - 1e-6 <= z <= z_hi + 1e-6:
            dropped += 1
            continue
        shutil.copy(f, out / f.name)
    assert dropped == 5
    return out


def _export(ct: Path, out: Path, *extra: str) -> tuple[int, str, str]:
    argv = ["export", "--dicom", str(ct), "--plan", str(DEMO / "plan.json"), "--out", str(out)]
    return _run([*argv, *extra])


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ref") / "out"
    code, _, err = _export(DEMO / "ct", out)
    assert code == 0, err
    return out


def test_slices_deleted_12_mm_below_the_path_change_nothing(
    tmp_path: Path, reference: Path
) -> None:
    # The demo path runs from z = -29 to -41 mm; slices at z = -53.4 .. -51.8 mm go missing.
    # A median-step affine shifted every slice above them by 2.0 mm; true positions do not.
    ct = _ct_without(tmp_path, -53.4, -51.8)
    out = tmp_path / "out"
    code, _, err = _export(ct, out)
    assert code == 0, err
    for name in ("profile.csv", "force.csv"):
        assert (out / name).read_text() == (reference / name).read_text()
    doc = json.loads((out / "summary.json").read_text())
    ref = json.loads((reference / "summary.json").read_text())
    assert doc["stop_depth_mm"] == ref["stop_depth_mm"]
    assert doc["interpolated_gaps"] == []
    assert "slice_gap" in [w["code"] for w in doc["warnings"]]


def test_slices_deleted_on_the_path_are_refused_or_interpolated_on_request(
    tmp_path: Path, reference: Path
) -> None:
    # Slices at z = -39.8 .. -38.2 mm missing: a 2.4 mm gap between -40.2 and -37.8 mm. The lip
    # (tip at z = -29 - x, rim 0.6 mm above it) reaches into it for 8.8 < x < 11.8 mm.
    ct = _ct_without(tmp_path, -39.8, -38.2)
    out = tmp_path / "out"
    code, stdout, err = _export(ct, out)
    assert code == 2 and stdout == "" and not out.exists()
    assert err.count("\n") == 1 and err.startswith("error: plan 'plan': ")
    assert "slice gap of 2.4 mm between the slices at -40.2 and -37.8 mm" in err
    assert "tip depths 8.8..11.8 mm" in err and "--interpolate-gaps" in err
    code, _, err = _export(ct, out, "--interpolate-gaps")
    assert code == 0, err
    doc = json.loads((out / "summary.json").read_text())
    assert doc["interpolated_gaps"] == [
        {
            "lower_mm": -40.2,
            "upper_mm": -37.8,
            "nominal_step_mm": 0.4,
            "depth_from_mm": 8.8,
            "depth_to_mm": 11.8,
        }
    ]
    codes = [w["code"] for w in doc["warnings"]]
    assert codes.count("gap_interpolated") == 1
    pairs = [(w["code"], w["message"]) for w in doc["warnings"]]
    assert len(pairs) == len(set(pairs))


def test_rehearse_refuses_a_crossed_gap_unless_asked(tmp_path: Path) -> None:
    ct = _ct_without(tmp_path, -39.8, -38.2)
    argv = ["rehearse", "--dicom", str(ct), "--plan", str(DEMO / "plan.json")]
    argv += ["--operator", "push:6", "--duration-s", "0.2"]
    code, _, err = _run([*argv, "--out", str(tmp_path / "a")])
    assert code == 2 and err.count("\n") == 1 and "slice gap of 2.4 mm" in err
    code, _, err = _run([*argv, "--out", str(tmp_path / "b"), "--interpolate-gaps"])
    assert code == 0, err
    doc = json.loads((tmp_path / "b" / "summary.json").read_text())
    # the rehearsal's summary carries the export's fields in the export's form
    assert len(doc["interpolated_gaps"]) == 1
    assert "gap_interpolated" in [w["code"] for w in doc["warnings"]]
