"""The phantom written as a case: DICOM round trip, plan and truth files, the bundled demo."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pydicom
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging import load_series
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.phantom.io import write_phantom
from ctdrill.imaging.phantom.mandible import Phantom, make_mandible_phantom
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.safety import max_safe_depth_mm
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
#: The command of assets/demo/README.md, as arguments.
DEMO_ARGS = ["--misch", "D2", "--noise-hu", "15", "--seed", "7"]


@pytest.fixture(scope="module")
def streaky(tmp_path_factory: pytest.TempPathFactory) -> tuple[Phantom, Path]:
    ph = make_mandible_phantom(misch="D3", noise_hu=30.0, metal_streak=True, seed=5)
    out = tmp_path_factory.mktemp("case")
    write_phantom(out, ph)
    return ph, out


def test_loaded_series_equals_the_phantom(streaky: tuple[Phantom, Path]) -> None:
    ph, out = streaky
    vol = load_series(out / "ct")
    assert vol.hu.dtype == np.int16
    np.testing.assert_array_equal(vol.hu, ph.hu)
    np.testing.assert_allclose(vol.affine_lps, ph.affine_lps, atol=1e-9)
    assert vol.valid is None and vol.warnings == ()
    assert vol.info.modality == "CT" and vol.info.is_hu
    # Canal location in the loaded series: the noise-free twin's centreline voxels are 30 HU.
    clean = make_mandible_phantom(misch="D3")
    clean_dir = out.parent / "clean"
    write_phantom(clean_dir, clean)
    loaded = load_series(clean_dir / "ct")
    np.testing.assert_allclose(loaded.sample(clean.canal_centerline_lps), 30.0, atol=1e-9)
    up = clean.canal_centerline_lps + np.array([0.0, 0.0, 1.2 + 0.4])  # one voxel above the roof
    np.testing.assert_array_equal(loaded.sample(up, order=0), clean.geometry.trabecular_hu)


def test_headers_are_realistic_and_synthetic(streaky: tuple[Phantom, Path]) -> None:
    ph, out = streaky
    files = sorted((out / "ct").glob("*.dcm"))
    assert len(files) == ph.hu.shape[0]
    ds = pydicom.dcmread(files[0])
    assert ds.Modality == "CT" and ds.SOPClassUID == "1.2.840.10008.5.1.4.1.1.2"
    assert float(ds.RescaleIntercept) == -1024.0 and float(ds.RescaleSlope) == 1.0
    assert ds.PixelRepresentation == 0 and ds.BitsStored == 12
    assert str(ds.PatientName) == "PHANTOM^MANDIBLE" and ds.PatientID == "PHANTOM-D3-S5"
    stored_max = max(int(pydicom.dcmread(f).pixel_array.max()) for f in files)
    assert stored_max == 4095  # the metal insert, 3071 HU
    assert ds.StudyDate == "" and ds.StudyTime == ""  # deterministic bytes: no dates (Type 2)


def test_plan_and_truth_files(streaky: tuple[Phantom, Path]) -> None:
    ph, out = streaky
    plan = load_plan(out / "plan.json")
    np.testing.assert_allclose(plan.entry_lps, ph.plan["entry_mm"])
    assert plan.planned_depth_mm == pytest.approx(12.0)
    assert plan.drill.diameter_mm == 2.0 and plan.calibration == "bone-illustrative"
    # The clearance code, on the written plan, finds the analytic max safe depth.
    assert max_safe_depth_mm(plan) == pytest.approx(ph.max_safe_depth_mm, abs=2e-3)
    truth = json.loads((out / "ground_truth.json").read_text(encoding="utf-8"))
    assert truth["format"] == "ctdrill-phantom-truth/1" and truth["misch"] == "D3"
    assert truth["hu"]["trabecular"] == 600.0 and truth["hu"]["metal"] == 3071.0
    assert truth["canal"]["radius_mm"] == 1.2
    np.testing.assert_array_equal(truth["canal"]["centerline_lps"], ph.canal_centerline_lps)
    assert truth["max_safe_depth_mm"] == pytest.approx(10.8)
    assert truth["affine_lps"] == ph.affine_lps.tolist()


def test_refuses_to_mix_series(streaky: tuple[Phantom, Path]) -> None:
    ph, out = streaky
    with pytest.raises(ImagingInputError, match="already holds files"):
        write_phantom(out, ph)


def test_demo_case_regenerates_byte_for_byte(tmp_path: Path) -> None:
    assert main(["phantom", str(tmp_path / "demo"), *DEMO_ARGS]) == 0
    fresh = sorted(p.relative_to(tmp_path / "demo") for p in (tmp_path / "demo").rglob("*.*"))
    bundled = sorted(p.relative_to(DEMO) for p in DEMO.rglob("*.*") if p.name != "README.md")
    assert fresh == bundled and len(bundled) == 82
    for rel in bundled:
        if rel.suffix == ".json":
            # Floats in the JSON files come from numpy trigonometry, whose last bit may differ
            # between numpy releases: the same document to 1e-12, not to the byte.
            _assert_same_json(
                json.loads((DEMO / rel).read_text(encoding="utf-8")),
                json.loads((tmp_path / "demo" / rel).read_text(encoding="utf-8")),
                str(rel),
            )
        else:
            assert (DEMO / rel).read_bytes() == (tmp_path / "demo" / rel).read_bytes(), rel
    assert sum((DEMO / rel).stat().st_size for rel in bundled) < 4_000_000


def _assert_same_json(a: object, b: object, where: str) -> None:
    if isinstance(a, float) or isinstance(b, float):
        assert isinstance(a, int | float) and isinstance(b, int | float), where
        assert a == pytest.approx(b, rel=1e-12, abs=1e-12), where
    elif isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for key in a:
            _assert_same_json(a[key], b[key], f"{where}/{key}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same_json(x, y, f"{where}[{i}]")
    else:
        assert a == b, where


def test_demo_readme_states_the_regenerating_command() -> None:
    text = (DEMO / "README.md").read_text(encoding="utf-8")
    assert "ctdrill phantom assets/demo " + " ".join(DEMO_ARGS) in text


def test_cli_bad_input_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["phantom", str(tmp_path / "x"), "--noise-hu", "-3"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: noise_hu") and err.count("\n") == 1
    with pytest.raises(SystemExit) as info:
        main(["phantom", str(tmp_path / "y"), "--misch", "D9"])
    assert info.value.code == 2
