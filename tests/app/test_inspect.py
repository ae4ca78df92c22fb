"""``ctdrill inspect``: the JSON contract and the error contract."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging.phantom.writer import write_series
from tests.imaging.factory import affine, linear_hu


def _json(args: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    assert main(["inspect", *args, "--json"]) == 0
    data: dict[str, object] = json.loads(capsys.readouterr().out)
    return data


def test_json_keys_and_exact_values(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    aff = affine((0.5, 0.75, 2.0), origin_lps=(1.0, 2.0, 3.0))
    hu = linear_hu((4, 5, 6))
    valid = np.ones(hu.shape, bool)
    valid[0, 0, 0] = False
    w = write_series(tmp_path, hu, aff, valid=valid, pixel_padding_value=-3000)
    data = _json([str(tmp_path)], capsys)
    assert data["dims"] == [6, 5, 4]
    assert data["spacing_mm"] == [0.5, 0.75, 2.0]
    np.testing.assert_allclose(np.array(data["affine_lps"]), aff, atol=1e-12)
    assert data["hu_min"] == float(hu[valid].min()) and data["hu_max"] == float(hu.max())
    # no raw UID without --include-phi: the SHA-256 plans record, computed here independently
    digest = hashlib.sha256(f"ctdrill-series/1:{w.series_uid}".encode()).hexdigest()
    assert data["series_uid"] == digest and data["series_uid_sha256"] == digest
    assert data["include_phi"] is False and w.series_uid not in json.dumps(data)
    raw = _json([str(tmp_path), "--include-phi"], capsys)
    assert raw["series_uid"] == w.series_uid and raw["series_uid_sha256"] == digest
    assert raw["include_phi"] is True
    assert data["warnings"][0] == {
        "code": "padding",
        "message": "1 padding voxels (PixelPaddingValue [-3000]) masked invalid",
    }
    (coarse,) = data["warnings"][1:]  # 2 mm slices, 0.75 mm rows
    assert coarse["code"] == "coarse_voxels"
    assert "slice step 2 mm, in-plane spacing 0.75 mm" in coarse["message"]
    assert data["slice_count"] == 4 and data["modality"] == "CT" and data["is_hu"] is True


def test_real_mixed_folder_and_series_option(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = shared_data / "dcmqa_ct_Philips_phantom_gantrytilt_mixedfolder"
    data = _json([str(folder)], capsys)
    assert data["dims"] == [512, 512, 58]
    codes = [w["code"] for w in data["warnings"]]  # type: ignore[attr-defined]
    assert codes == [
        "multiple_series",
        "localizer_dropped",
        "files_skipped",
        "gantry_tilt",
        "coarse_voxels",
    ]
    series = data["series"]
    assert [s["slices"] for s in series] == [58, 54]  # type: ignore[attr-defined]
    other = series[1]["series_uid"]  # type: ignore[index]
    assert len(other) == 64 and "description" not in series[1]  # type: ignore[index]
    data2 = _json([str(folder), "--series", other], capsys)
    assert data2["dims"] == [512, 512, 54] and data2["series_uid"] == other
    # the 12-digit label that warnings print selects it too, as does the raw UID
    label = other[:12]
    assert label in data["warnings"][0]["message"]  # type: ignore[index]
    assert _json([str(folder), "--series", label], capsys)["series_uid"] == other
    raw = _json([str(folder), "--include-phi"], capsys)["series"][1]  # type: ignore[index]
    assert raw["series_uid"].startswith("1.")  # type: ignore[index]
    by_uid = _json([str(folder), "--series", raw["series_uid"]], capsys)  # type: ignore[index]
    assert by_uid["series_uid"] == other


def test_text_summary(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["inspect", str(shared_data / "dcmqa_ct_GE_head_gantrytilt_varspacing")]) == 0
    out = capsys.readouterr().out
    assert "512 cols x 512 rows x 28 slices" in out
    for code in ("gantry_tilt", "nonuniform_spacing", "padding"):
        assert f"{code}:" in out


@pytest.mark.parametrize("sub", ["missing", "empty"])
def test_bad_folder_is_exit_2_with_one_error_line(
    tmp_path: Path, sub: str, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "empty").mkdir()
    assert main(["inspect", str(tmp_path / sub), "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(tmp_path / sub) in lines[0]


def test_refused_series_is_exit_2(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = shared_data / "dicom2nifti_ct_geometry_edgecases" / "notavolume_siemens_same_position"
    assert main(["inspect", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "not a volume" in err
