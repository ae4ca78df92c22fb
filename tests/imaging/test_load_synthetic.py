"""load_series on series written with known geometry and values: exact answers."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pydicom
import pytest
from pydicom.uid import JPEG2000Lossless, RLELossless, SecondaryCaptureImageStorage

from ctdrill.imaging import (
    ImagingInputError,
    calibrate_grey_to_hu,
    list_series,
    load_series,
    resample_uniform_slices,
)
from ctdrill.imaging.dicom.series import DuplicateSliceError, MemoryCapError
from tests.imaging.factory import affine, linear_hu, rotation, volume, write

SHAPE = (5, 6, 7)


def _same_field(a: np.ndarray, b: np.ndarray, aff: np.ndarray, loaded_aff: np.ndarray) -> None:
    """The loaded volume describes the same HU field in LPS as the one written."""
    ref, got = volume(a, aff), volume(b, loaded_aff)
    k, j, i = np.indices(a.shape)
    pts = ref.index_to_lps(np.stack([i, j, k], -1).reshape(-1, 3).astype(float))
    np.testing.assert_allclose(got.sample(pts), ref.sample(pts), atol=1e-6)


def test_oblique_non_square_exact(tmp_path: Path) -> None:
    aff = affine((0.35, 0.45, 1.25), rot=rotation(20, 35, -15), origin_lps=(3.0, -4.0, 5.0))
    hu = linear_hu(SHAPE)
    write(tmp_path, hu, aff, shuffle_names=True, instance_numbers=[5, 1, 4, 2, 3])
    v = load_series(tmp_path)
    np.testing.assert_allclose(v.affine_lps, aff, atol=1e-9)
    np.testing.assert_array_equal(v.hu, hu)
    assert v.hu.dtype == np.int16 and v.valid is None
    assert v.warnings == ()  # 1.25 mm slices are not coarse yet (the limit is "above 1.25")
    assert v.dims == (7, 6, 5)
    np.testing.assert_allclose(v.spacing_mm, (0.35, 0.45, 1.25), rtol=1e-9)


def test_gantry_tilt_gives_the_exact_sheared_affine(tmp_path: Path) -> None:
    aff = affine((0.5, 0.5, 2.0), tilt_deg=18.5)
    write(tmp_path, linear_hu(SHAPE), aff, gantry_tilt_deg=18.5)
    v = load_series(tmp_path)
    np.testing.assert_allclose(v.affine_lps, aff, atol=1e-9)
    assert v.warning_codes == ("gantry_tilt", "coarse_voxels")  # 2 mm slices
    assert v.info.gantry_tilt_deg == pytest.approx(18.5, abs=1e-6)
    np.testing.assert_allclose(np.diff(v.slice_positions_mm), 2.0, atol=1e-9)


def test_tilt_detected_without_the_tilt_tag(tmp_path: Path) -> None:
    write(tmp_path, linear_hu(SHAPE), affine((0.5, 0.5, 2.0), tilt_deg=-7.0))
    v = load_series(tmp_path)
    assert v.warning_codes == ("gantry_tilt", "coarse_voxels")
    assert v.info.gantry_tilt_deg == pytest.approx(7.0, abs=1e-6)


def test_feet_first_descending_slices_are_reordered(tmp_path: Path) -> None:
    aff = affine((0.5, 0.5, -1.5), origin_lps=(0, 0, 100.0))  # k column against the normal
    hu = linear_hu(SHAPE)
    write(tmp_path, hu, aff)
    v = load_series(tmp_path)
    np.testing.assert_array_equal(v.hu, hu[::-1])
    np.testing.assert_allclose(v.affine_lps[:3, 2], [0, 0, 1.5], atol=1e-12)
    np.testing.assert_allclose(v.affine_lps[:3, 3], [0, 0, 100.0 - 4 * 1.5], atol=1e-12)
    assert np.all(np.diff(v.slice_positions_mm) > 0)
    _same_field(hu, v.hu, aff, v.affine_lps)


def test_unsigned_12_bit_with_garbage_high_bits(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    write(tmp_path, hu, affine(), unsigned=True, bits_stored=12, high_bits_fill=0b1111)
    v = load_series(tmp_path)
    np.testing.assert_array_equal(v.hu, hu)
    assert v.hu.dtype == np.int16


def test_signed_12_bit_with_garbage_high_bits(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE, c0=-1500)  # negative stored values need the sign extension
    write(tmp_path, hu, affine(), bits_stored=12, high_bits_fill=0b0101)
    np.testing.assert_array_equal(load_series(tmp_path).hu, hu)


def test_non_integer_rescale_gives_float32(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE).astype(np.float64) + 0.25
    write(tmp_path, hu, affine(), rescale_slope=0.25, rescale_intercept=-1024.0)
    v = load_series(tmp_path)
    assert v.hu.dtype == np.float32
    np.testing.assert_array_equal(v.hu, hu.astype(np.float32))


def test_int16_overflowing_rescale_promotes_to_float32(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE).astype(np.int64) * 100  # up to ~40 000 HU
    write(tmp_path, hu, affine(), rescale_slope=100.0, rescale_intercept=0.0)
    v = load_series(tmp_path)
    assert v.hu.dtype == np.float32
    np.testing.assert_array_equal(v.hu, hu.astype(np.float32))


def test_slice_gap_is_reported_not_interpolated(tmp_path: Path) -> None:
    aff = affine((0.5, 0.5, 1.0))
    z = np.array([0.0, 1.0, 2.0, 4.0, 5.0])
    pos = aff[:3, 3] + z[:, None] * np.array([0, 0, 1.0])
    write(tmp_path, linear_hu(SHAPE), aff, positions_lps=pos)
    v = load_series(tmp_path)
    assert v.warning_codes == ("slice_gap",)
    assert "1 slice(s) missing" in v.warnings[0].message
    np.testing.assert_allclose(v.slice_positions_mm - v.slice_positions_mm[0], z)
    np.testing.assert_allclose(v.affine_lps, aff, atol=1e-9)  # median step
    assert v.hu.shape[0] == 5 and not v.uniform_slices()


def test_nonuniform_spacing_keeps_true_positions(tmp_path: Path) -> None:
    aff = affine((0.5, 0.5, 1.0))
    z = np.array([0.0, 1.0, 2.0, 3.5, 4.5])
    pos = aff[:3, 3] + z[:, None] * np.array([0, 0, 1.0])
    write(tmp_path, linear_hu(SHAPE), aff, positions_lps=pos)
    v = load_series(tmp_path)
    assert v.warning_codes == ("nonuniform_spacing",)
    np.testing.assert_allclose(v.slice_positions_mm - v.slice_positions_mm[0], z)
    assert v.spacing_mm[2] == pytest.approx(1.0)


def test_identical_duplicates_are_dropped(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    aff = affine()
    write(tmp_path, hu, aff, name_prefix="A")
    write(tmp_path, hu[2:4], aff @ _shift_k(2), name_prefix="B", series_uid=_uid(tmp_path))
    v = load_series(tmp_path)
    assert v.warning_codes == ("duplicate_slice",)
    assert "2 identical duplicate" in v.warnings[0].message
    np.testing.assert_array_equal(v.hu, hu)


def test_conflicting_duplicates_are_refused(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    aff = affine()
    write(tmp_path, hu, aff, name_prefix="A")
    write(tmp_path, hu[2:3] + 1, aff @ _shift_k(2), name_prefix="B", series_uid=_uid(tmp_path))
    with pytest.raises(DuplicateSliceError, match=r"A00002\.dcm.*B00000\.dcm|B00000\.dcm.*A00002"):
        load_series(tmp_path)


def _shift_k(k: int) -> np.ndarray:
    s = np.eye(4)
    s[2, 3] = k
    return s


def _uid(folder: Path) -> str:
    return str(pydicom.dcmread(next(folder.glob("A*.dcm"))).SeriesInstanceUID)


def test_memory_cap_is_checked_before_decoding(tmp_path: Path) -> None:
    write(tmp_path, linear_hu(SHAPE), affine())
    need = 5 * 6 * 7 * 2
    with pytest.raises(MemoryCapError, match="raise max_bytes"):
        load_series(tmp_path, max_bytes=need - 1)
    assert load_series(tmp_path, max_bytes=need).hu.nbytes == need


def test_padding_mask_and_range_limit(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    valid = np.ones(SHAPE, bool)
    valid[:, :2, :] = False
    write(tmp_path / "a", hu, affine(), valid=valid, pixel_padding_value=-2000)
    v = load_series(tmp_path / "a")
    np.testing.assert_array_equal(v.valid, valid)
    assert v.warning_codes == ("padding",)
    np.testing.assert_array_equal(v.hu[valid], hu[valid])
    np.testing.assert_array_equal(v.hu[~valid], -2000)
    # A range limit masks every stored value between the two (here -3000 .. -1100).
    hu2 = hu.copy()
    hu2[0, 0, :3] = [-3000, -1100, -1099]
    write(
        tmp_path / "b",
        hu2,
        affine(),
        pixel_padding_value=-3000,
        pixel_padding_range_limit=-1100,
    )
    v2 = load_series(tmp_path / "b")
    assert v2.valid is not None
    assert list(v2.valid[0, 0, :3]) == [False, False, True]
    assert int((~v2.valid).sum()) == 2


def test_one_slice_loads_but_is_not_a_volume(tmp_path: Path) -> None:
    write(tmp_path, linear_hu((1, 6, 7)), affine((0.5, 0.5, 1.0)), slice_thickness_mm=2.5)
    v = load_series(tmp_path)
    assert not v.is_volume
    assert v.warning_codes == ("single_slice", "coarse_voxels")  # 2.5 mm thick
    assert v.spacing_mm[2] == pytest.approx(2.5)


def test_localizers_other_series_and_non_image_files(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    a = write(tmp_path / "s1", hu, affine(), name_prefix="AX")
    # A localizer in the same series with another orientation, and one tagged LOCALIZER.
    write(
        tmp_path / "s1",
        linear_hu((1, 6, 7)),
        affine(rot=rotation(0, 90, 0)),
        name_prefix="LOC",
        series_uid=a.series_uid,
    )
    write(
        tmp_path / "s3",
        linear_hu((1, 6, 7)),
        affine(),
        image_type=("ORIGINAL", "PRIMARY", "LOCALIZER"),
    )
    b = write(tmp_path / "s2", linear_hu((3, 6, 7)), affine(), seed=7)
    write(
        tmp_path / "sc", linear_hu((1, 6, 7)), affine(), sop_class_uid=SecondaryCaptureImageStorage
    )
    (tmp_path / "notes.txt").write_text("not dicom")
    (tmp_path / "blob.bin").write_bytes(b"\x08\x00\x05\x00" + bytes(300))
    v = load_series(tmp_path)
    assert v.info.series_uid == a.series_uid
    np.testing.assert_array_equal(v.hu, hu)
    assert v.warning_codes == ("multiple_series", "localizer_dropped", "files_skipped")
    # the other series is named by its UID's hash, never the UID (no raw UID in any output)
    b_label = hashlib.sha256(f"ctdrill-series/1:{b.series_uid}".encode()).hexdigest()[:12]
    assert f"{b_label} (3 slices)" in v.warnings[0].message
    assert b.series_uid not in v.warnings[0].message
    assert load_series(tmp_path, series_uid=b_label).hu.shape == (3, 6, 7)
    assert "2 localizer" in v.warnings[1].message
    assert "1 non-volume" in v.warnings[2].message
    other = load_series(tmp_path, series_uid=b.series_uid)
    assert other.hu.shape == (3, 6, 7)
    assert [s.series_uid for s in list_series(tmp_path)] == [a.series_uid, b.series_uid]
    with pytest.raises(ImagingInputError, match="not found; available CT series"):
        load_series(tmp_path, series_uid="1.2.3.4")


def test_preamble_less_files_load_and_junk_is_ignored(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    write(tmp_path, hu, affine(), preamble=False)
    (tmp_path / "README").write_text("hello")
    v = load_series(tmp_path)
    np.testing.assert_array_equal(v.hu, hu)
    assert v.warnings == ()


def test_missing_geometry_is_refused(tmp_path: Path) -> None:
    w = write(tmp_path, linear_hu(SHAPE), affine())
    ds = pydicom.dcmread(w.paths[3])
    del ds.ImagePositionPatient
    ds.save_as(w.paths[3])
    with pytest.raises(ImagingInputError, match=r"IM00003\.dcm: missing .*ImagePositionPatient"):
        load_series(tmp_path)


def test_no_ct_at_all_is_refused(tmp_path: Path) -> None:
    (tmp_path / "a.txt").write_text("x")
    with pytest.raises(ImagingInputError, match="no CT image series"):
        load_series(tmp_path)
    with pytest.raises(ImagingInputError, match="no such file or folder"):
        load_series(tmp_path / "missing")


@pytest.mark.parametrize("syntax", [RLELossless, JPEG2000Lossless])
def test_compressed_series_equal_the_uncompressed_values(tmp_path: Path, syntax: str) -> None:
    hu = linear_hu((3, 32, 32))
    write(tmp_path, hu, affine(), transfer_syntax=syntax)
    v = load_series(tmp_path)
    np.testing.assert_array_equal(v.hu, hu)
    assert v.info.transfer_syntax == syntax
    assert v.warnings == ()


def test_lossy_flag_and_not_hu(tmp_path: Path) -> None:
    write(tmp_path / "a", linear_hu(SHAPE), affine(), extra={"LossyImageCompression": "01"})
    assert load_series(tmp_path / "a").warning_codes == ("lossy_compression",)
    write(tmp_path / "b", linear_hu(SHAPE), affine(), rescale_type="US")
    vb = load_series(tmp_path / "b")
    assert vb.warning_codes == ("not_hu",) and not vb.info.is_hu
    write(tmp_path / "c", linear_hu(SHAPE), affine(), write_rescale=False)
    vc = load_series(tmp_path / "c")
    assert vc.warning_codes == ("not_hu",) and not vc.info.is_hu


def test_grey_to_hu_calibration_on_a_synthetic_volume() -> None:
    # Grey = (HU + 1000) / 2 + 30: air at grey 30, water at grey 530.
    hu_true = np.full((4, 8, 8), -1000.0)
    hu_true[:, 4:, :] = 0.0
    hu_true[:, 6:, 6:] = 1200.0
    grey = ((hu_true + 1000.0) / 2.0 + 30.0).astype(np.int16)
    v = volume(grey, affine())
    cal = calibrate_grey_to_hu(
        v, air_region=np.s_[:, :2, :], bone_or_water_region=np.s_[:, 4:6, :4], reference_hu=0.0
    )
    np.testing.assert_allclose(cal.hu, hu_true, atol=1e-3)
    assert cal.info.is_hu and "calibrated" in cal.info.rescale_type
    with pytest.raises(ImagingInputError, match="different material"):
        calibrate_grey_to_hu(v, air_region=np.s_[:, :1], bone_or_water_region=np.s_[:, 1:2])


def _patch(path: Path, old: bytes, new: bytes) -> None:
    data = path.read_bytes()
    assert data.count(old) == 1
    path.write_bytes(data.replace(old, new))


@pytest.mark.filterwarnings("ignore:Invalid value for VR")
def test_damaged_values_are_refused_naming_file_and_field(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    cases: dict[str, tuple[dict[str, object], str]] = {
        "slope0": ({"RescaleSlope": "0"}, "RescaleSlope 0"),
        "nanslope": ({"RescaleSlope": "nan"}, "RescaleSlope nan"),
        "infpos": ({"ImagePositionPatient": ["inf", "0", "0"]}, "ImagePositionPatient"),
        "nanspacing": ({"PixelSpacing": ["nan", "nan"]}, "PixelSpacing"),
    }
    for name, (values, match) in cases.items():
        w = write(tmp_path / name, hu, affine())
        ds = pydicom.dcmread(w.paths[2])
        for keyword, value in values.items():
            setattr(ds, keyword, value)
        ds.save_as(w.paths[2])
        with pytest.raises(ImagingInputError, match=match) as info:
            load_series(tmp_path / name)
        assert "IM00002.dcm" in str(info.value)


def test_pixel_length_bombs_and_frame_bombs_are_refused(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    nbytes = (6 * 7 * 2).to_bytes(4, "little")
    # PixelData declaring 4 GB in a small file (an incomplete copy).
    w = write(tmp_path / "long", hu, affine())
    _patch(
        w.paths[1],
        b"\xe0\x7f\x10\x00OW\x00\x00" + nbytes,
        b"\xe0\x7f\x10\x00OW\x00\x00\xf0\xff\xff\xff",
    )
    with pytest.raises(ImagingInputError, match=r"IM00001\.dcm: PixelData declares 4294967280"):
        load_series(tmp_path / "long")
    # NumberOfFrames far beyond the pixel data.
    w = write(tmp_path / "frames", hu, affine(), extra={"NumberOfFrames": 2147483647})
    with pytest.raises(ImagingInputError):
        load_series(tmp_path / "frames")
    # Pixel data shorter than Rows x Columns.
    w = write(tmp_path / "short", hu, affine())
    ds = pydicom.dcmread(w.paths[0])
    ds.PixelData = ds.PixelData[:20]
    ds.save_as(w.paths[0])
    with pytest.raises(ImagingInputError, match=r"IM00000\.dcm: PixelData holds 20 bytes"):
        load_series(tmp_path / "short")


def test_unknown_transfer_syntax_is_refused(tmp_path: Path) -> None:
    w = write(tmp_path, linear_hu(SHAPE), affine())
    for p in w.paths:
        ds = pydicom.dcmread(p)
        ds.file_meta.TransferSyntaxUID = pydicom.uid.UID("1.2.840.12008.1.2.1")
        ds.save_as(p, implicit_vr=False, little_endian=True, enforce_file_format=True)
    with pytest.raises(ImagingInputError, match="not a known DICOM transfer syntax"):
        load_series(tmp_path)


def test_deflated_series_loads(tmp_path: Path) -> None:
    hu = linear_hu(SHAPE)
    w = write(tmp_path, hu, affine())
    for p in w.paths:
        ds = pydicom.dcmread(p)
        ds.file_meta.TransferSyntaxUID = pydicom.uid.DeflatedExplicitVRLittleEndian
        ds.save_as(p, enforce_file_format=True)
    v = load_series(tmp_path)
    np.testing.assert_array_equal(v.hu, hu)
    assert v.info.transfer_syntax == pydicom.uid.DeflatedExplicitVRLittleEndian


def test_explicit_resampling_of_an_irregular_tilted_stack(tmp_path: Path) -> None:
    aff = affine((0.5, 0.5, 1.0), tilt_deg=10.0)
    z = np.array([0.0, 1.0, 2.0, 4.0, 5.5, 6.0])  # a gap and irregular steps
    k_true = z  # normal distance in units of the 1 mm step
    pos = aff[:3, 3] + z[:, None] * aff[:3, 2]
    shape = (6, 4, 5)
    kk, j, i = np.indices(shape)
    hu = (3 * i + 7 * j + 40 * k_true[kk] - 300).astype(np.int16)  # linear along the normal
    write(tmp_path, hu, aff, positions_lps=pos)
    v = load_series(tmp_path)
    assert set(v.warning_codes) == {"gantry_tilt", "slice_gap", "nonuniform_spacing"}
    r = resample_uniform_slices(v)
    assert r.warning_codes == ("gantry_tilt",) and r.info.resampled and r.uniform_slices()
    assert r.hu.shape == (7, 4, 5)
    np.testing.assert_allclose(r.affine_lps, aff, atol=1e-9)
    k, j, i = np.indices(r.hu.shape)
    np.testing.assert_allclose(r.hu, 3 * i + 7 * j + 40 * k - 300, atol=1e-3)
    # The same LPS point samples the same (linear) value in both volumes.
    pts = r.index_to_lps(np.array([[1.5, 2.0, 2.5], [4.0, 3.0, 6.0]]))
    np.testing.assert_allclose(r.sample(pts), [3 * 1.5 + 14 + 100 - 300, 12 + 21 + 240 - 300])
    with pytest.raises(ImagingInputError, match="step_mm"):
        resample_uniform_slices(v, step_mm=0.0)
