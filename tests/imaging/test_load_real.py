"""Every real series in ../shared/data loads (or is refused) as its README table says."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pydicom
import pytest

from ctdrill.imaging import CTVolume, ImagingInputError, load_series
from ctdrill.imaging.dicom.series import DuplicateSliceError

GE = "dcmqa_ct_GE_head_gantrytilt_varspacing"
MIXED = "dcmqa_ct_Philips_phantom_gantrytilt_mixedfolder"
NOTILT = "dcmqa_ct_Philips_phantom_notilt_5mm"
DCMQI = "dcmqi_ct_3slice_GE_abdomen"
EDGE = "dicom2nifti_ct_geometry_edgecases"
SINGLE = "single_slice_ct"


def _headers_by_position(folder: Path, series_uid: str) -> list[pydicom.Dataset]:
    """IPP/IOP read independently with pydicom, sorted along the normal."""
    out = []
    for p in folder.rglob("*"):
        if not p.is_file():
            continue
        try:
            ds = pydicom.dcmread(p, stop_before_pixels=True)
        except pydicom.errors.InvalidDicomError:
            continue
        if ds.get("SeriesInstanceUID") == series_uid and "ImagePositionPatient" in ds:
            out.append(ds)
    iop = np.array(out[0].ImageOrientationPatient, dtype=float)
    normal = np.cross(iop[:3], iop[3:])
    return sorted(out, key=lambda d: float(np.array(d.ImagePositionPatient, float) @ normal))


def _check_ipp_matches(v: CTVolume, folder: Path, *, uniform: bool) -> None:
    headers = _headers_by_position(folder, v.info.series_uid)
    assert len(headers) == v.hu.shape[0]
    ipp = np.array([d.ImagePositionPatient for d in headers], dtype=float)
    np.testing.assert_allclose(v.affine_lps[:3, 3], ipp[0], atol=1e-6)
    if uniform:
        k = np.arange(len(ipp), dtype=float)
        np.testing.assert_allclose(v.index_to_lps(np.c_[0 * k, 0 * k, k]), ipp, atol=2e-3)
    iop = np.array(headers[0].ImageOrientationPatient, dtype=float)
    normal = np.cross(iop[:3], iop[3:])
    np.testing.assert_allclose(v.slice_positions_mm, ipp @ normal, atol=1e-6)


def test_ge_head_tilt_variable_spacing_padding(shared_data: Path) -> None:
    v = load_series(shared_data / GE)
    assert set(v.warning_codes) == {"gantry_tilt", "nonuniform_spacing", "padding", "coarse_voxels"}
    assert v.dims == (512, 512, 28)
    assert v.info.gantry_tilt_deg == pytest.approx(18.5, abs=0.05)
    steps = np.round(np.diff(v.slice_positions_mm), 2)
    assert set(steps) == {4.0, 7.0, 1.08}
    assert not v.uniform_slices()
    assert v.valid is not None
    np.testing.assert_array_equal(v.hu[~v.valid], -1500)
    assert v.hu[v.valid].max() == 2121
    _check_ipp_matches(v, shared_data / GE, uniform=False)


def test_philips_mixed_folder_picks_the_58_slice_series(shared_data: Path) -> None:
    v = load_series(shared_data / MIXED)
    assert v.warning_codes == (
        "multiple_series",
        "localizer_dropped",
        "files_skipped",
        "gantry_tilt",
        "coarse_voxels",
    )
    assert v.dims == (512, 512, 58)
    assert v.info.gantry_tilt_deg == pytest.approx(16.5, abs=0.05)
    assert v.spacing_mm[0] == pytest.approx(0.40625)
    assert "(54 slices)" in v.warnings[0].message
    assert v.hu.min() == -1024 and v.hu.max() == 804
    _check_ipp_matches(v, shared_data / MIXED, uniform=True)
    # The k column is the IPP step (table motion), not the slice normal: a sheared affine.
    kcol = v.affine_lps[:3, 2]
    normal = np.cross(v.affine_lps[:3, 0], v.affine_lps[:3, 1])
    cos = abs(kcol @ normal) / np.linalg.norm(kcol) / np.linalg.norm(normal)
    assert np.degrees(np.arccos(cos)) == pytest.approx(16.5, abs=0.05)


def test_philips_mixed_folder_other_series_by_uid(shared_data: Path) -> None:
    first = load_series(shared_data / MIXED)
    other_uid = first.warnings[0].message.split("also present: ")[1].split(" ")[0]
    v = load_series(shared_data / MIXED, series_uid=other_uid)
    assert v.dims == (512, 512, 54)
    assert v.info.gantry_tilt_deg == pytest.approx(18.5, abs=0.05)
    assert "multiple_series" in v.warning_codes
    _check_ipp_matches(v, shared_data / MIXED, uniform=True)


def test_philips_notilt_is_clean_but_coarse(shared_data: Path) -> None:
    v = load_series(shared_data / NOTILT)
    assert v.warning_codes == ("coarse_voxels",)  # 5 mm slices: nothing else to say
    assert "slice step 5 mm, slice thickness 5 mm" in v.warnings[0].message
    assert "+-2.5 mm" in v.warnings[0].message and "whole millimetres" in v.warnings[0].message
    assert v.dims == (512, 512, 28)
    np.testing.assert_allclose(v.spacing_mm, (0.451171875, 0.451171875, 5.0), atol=1e-6)
    assert (v.hu.min(), v.hu.max()) == (-1024, 782)
    assert v.affine_lps[2, 3] == pytest.approx(696.21, abs=0.01)
    _check_ipp_matches(v, shared_data / NOTILT, uniform=True)


def test_dcmqi_feet_first_padding_ordered_by_position(shared_data: Path) -> None:
    v = load_series(shared_data / DCMQI)
    assert v.warning_codes == ("padding", "coarse_voxels")
    assert v.valid is not None
    np.testing.assert_array_equal(v.hu[~v.valid], -3024)
    assert (v.hu[v.valid].min(), v.hu[v.valid].max()) == (-1024, 1381)
    headers = _headers_by_position(shared_data / DCMQI, v.info.series_uid)
    numbers = [int(d.InstanceNumber) for d in headers]
    assert numbers == sorted(numbers, reverse=True)  # InstanceNumber runs against z
    for k, d in enumerate(headers):
        arr = pydicom.dcmread(d.filename).pixel_array.astype(int) - 1024
        np.testing.assert_array_equal(v.hu[k], arr)
    _check_ipp_matches(v, shared_data / DCMQI, uniform=True)


@pytest.mark.parametrize(
    ("case", "codes", "tilt"),
    [
        ("gantrytilting_siemens_14deg", {"gantry_tilt"}, 14.0),
        ("sliceincrement_ge_missing_slice", {"slice_gap"}, 0.0),
        ("sliceincrement_siemens_tilt_missing_slice", {"gantry_tilt", "slice_gap"}, 15.5),
    ],
)
def test_dicom2nifti_geometry_cases(
    shared_data: Path, case: str, codes: set[str], tilt: float
) -> None:
    v = load_series(shared_data / EDGE / case)
    assert set(v.warning_codes) == codes | {"coarse_voxels"}
    assert v.info.gantry_tilt_deg == pytest.approx(tilt, abs=0.05)
    assert v.hu.shape[0] == 4


def test_dicom2nifti_same_position_is_not_a_volume(shared_data: Path) -> None:
    with pytest.raises(DuplicateSliceError, match="4 different images at slice position"):
        load_series(shared_data / EDGE / "notavolume_siemens_same_position")


def test_enhanced_ct_multiframe_loads_with_not_hu(shared_data: Path) -> None:
    v = load_series(shared_data / SINGLE / "pydicom_data_repo")
    assert v.warning_codes == ("not_hu", "coarse_voxels")  # 10 mm apart
    assert not v.info.is_hu and v.info.rescale_type == "US"
    assert v.dims == (512, 512, 2)
    np.testing.assert_allclose(v.spacing_mm, (0.388672, 0.388672, 10.0), atol=1e-6)
    # IOP [-1,0,0, 0,1,0]: the normal is -z, so the frame at z=-149 comes first.
    np.testing.assert_allclose(v.affine_lps[:3, 0], [-0.388672, 0, 0], atol=1e-6)
    assert v.affine_lps[2, 3] == pytest.approx(-149.0)
    np.testing.assert_allclose(v.affine_lps[:3, 2], [0, 0, -10.0], atol=1e-9)


def test_rt_planning_single_slice_is_marked(shared_data: Path) -> None:
    v = load_series(shared_data / SINGLE / "dicompyler_core")
    assert v.warning_codes == ("single_slice", "coarse_voxels") and not v.is_volume
    assert (v.hu.min(), v.hu.max()) == (-1000, 1457)
    assert v.spacing_mm[2] == pytest.approx(3.0)


def test_colour_pictures_are_refused(shared_data: Path) -> None:
    with pytest.raises(ImagingInputError, match="not a CT volume"):
        load_series(shared_data / SINGLE / "deid_data_pypi")


def test_whole_single_slice_folder_picks_the_multiframe(shared_data: Path) -> None:
    v = load_series(shared_data / SINGLE)
    assert v.warning_codes == ("multiple_series", "files_skipped", "not_hu", "coarse_voxels")
    assert v.hu.shape[0] == 2
