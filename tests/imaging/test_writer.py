"""The DICOM writer: tags read back with pydicom match the affine and the options exactly."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pydicom
import pytest
from pydicom.uid import ImplicitVRLittleEndian, RLELossless

from ctdrill.imaging.phantom.writer import WriterInputError, write_series
from tests.conftest import ASSETS
from tests.imaging.factory import affine, linear_hu, rotation

ROT = rotation(30.0, 15.0, -20.0)


def test_geometry_tags_follow_the_affine(tmp_path: Path) -> None:
    aff = affine((0.3, 0.8, 1.7), rot=ROT, origin_lps=(5.5, -7.25, 100.0), tilt_deg=9.0)
    hu = linear_hu((4, 6, 5))
    w = write_series(tmp_path, hu, aff, patient_name="Test^Phantom", patient_id="P1")
    for k, path in enumerate(w.paths):
        ds = pydicom.dcmread(path)
        np.testing.assert_allclose(ds.ImageOrientationPatient[:3], ROT[:, 0], atol=1e-9)
        np.testing.assert_allclose(ds.ImageOrientationPatient[3:], ROT[:, 1], atol=1e-9)
        # PixelSpacing is (row spacing, column spacing): |column 1|, then |column 0|.
        np.testing.assert_allclose([float(v) for v in ds.PixelSpacing], [0.8, 0.3], rtol=1e-10)
        expected_ipp = aff[:3, 3] + k * aff[:3, 2]
        np.testing.assert_allclose(
            [float(v) for v in ds.ImagePositionPatient], expected_ipp, atol=1e-8
        )
        assert ds.Rows == 6 and ds.Columns == 5
        assert str(ds.PatientName) == "Test^Phantom" and ds.PatientID == "P1"
        assert ds.SOPClassUID == "1.2.840.10008.5.1.4.1.1.2"
        assert ds.SeriesInstanceUID == w.series_uid
        np.testing.assert_array_equal(ds.pixel_array, hu[k])
    uids = {pydicom.dcmread(p).SOPInstanceUID for p in w.paths}
    assert len(uids) == 4


def test_unsigned_12_bit_with_garbage_high_bits(tmp_path: Path) -> None:
    hu = linear_hu((2, 3, 4))
    w = write_series(tmp_path, hu, affine(), unsigned=True, bits_stored=12, high_bits_fill=0b1011)
    ds = pydicom.dcmread(w.paths[1])
    assert (ds.PixelRepresentation, ds.BitsStored, ds.HighBit) == (0, 12, 11)
    assert float(ds.RescaleIntercept) == -1024.0
    raw = np.frombuffer(ds.PixelData, dtype="<u2").reshape(3, 4)
    np.testing.assert_array_equal(raw >> 12, 0b1011)
    np.testing.assert_array_equal(raw & 0x0FFF, hu[1] + 1024)


def test_padding_value_replaces_invalid_voxels(tmp_path: Path) -> None:
    hu = linear_hu((1, 3, 3))
    valid = np.ones(hu.shape, bool)
    valid[0, 0, 0] = False
    w = write_series(tmp_path, hu, affine(), valid=valid, pixel_padding_value=-2000)
    ds = pydicom.dcmread(w.paths[0])
    assert ds.PixelPaddingValue == -2000
    assert ds.pixel_array[0, 0] == -2000 and ds.pixel_array[1, 1] == hu[0, 1, 1]


def test_shuffled_names_implicit_vr_and_no_preamble(tmp_path: Path) -> None:
    hu = linear_hu((12, 2, 2))
    w = write_series(
        tmp_path / "a", hu, affine(), shuffle_names=True, transfer_syntax=ImplicitVRLittleEndian
    )
    names = [p.name for p in w.paths]
    assert sorted(names) != names and len(set(names)) == 12
    ds = pydicom.dcmread(w.paths[0])
    assert ds.file_meta.TransferSyntaxUID == ImplicitVRLittleEndian
    bare = write_series(tmp_path / "b", hu[:1], affine(), preamble=False)
    assert bare.paths[0].read_bytes()[128:132] != b"DICM"


def test_rle_round_trip(tmp_path: Path) -> None:
    hu = linear_hu((2, 16, 16))
    w = write_series(tmp_path, hu, affine(), transfer_syntax=RLELossless)
    ds = pydicom.dcmread(w.paths[1])
    assert ds.file_meta.TransferSyntaxUID == RLELossless
    np.testing.assert_array_equal(ds.pixel_array, hu[1])


def test_float_rescale_and_explicit_positions(tmp_path: Path) -> None:
    hu = np.array([[[0.0, 0.5], [1.5, -1000.0]]] * 2)
    pos = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 3.0]])
    w = write_series(tmp_path, hu, affine(), rescale_slope=0.5, positions_lps=pos)
    ds = pydicom.dcmread(w.paths[1])
    assert [float(v) for v in ds.ImagePositionPatient] == [0.0, 0.0, 3.0]
    np.testing.assert_array_equal(ds.pixel_array * 0.5, hu[1])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"unsigned": True, "rescale_intercept": 0.0}, "do not fit"),
        ({"bits_stored": 8}, "do not fit"),
        ({"valid": np.zeros((2, 3, 4), bool)}, "pixel_padding_value"),
        ({"bits_stored": 17}, "BitsStored"),
    ],
)
def test_bad_options_are_refused(tmp_path: Path, kwargs: dict[str, object], match: str) -> None:
    hu = linear_hu((2, 3, 4))
    with pytest.raises(WriterInputError, match=match):
        write_series(tmp_path, hu, affine(), **kwargs)  # type: ignore[arg-type]


def test_non_orthogonal_in_plane_axes_are_refused(tmp_path: Path) -> None:
    aff = affine()
    aff[:3, 1] += aff[:3, 0] * 0.2
    with pytest.raises(WriterInputError, match="orthogonal"):
        write_series(tmp_path, linear_hu((1, 2, 2)), aff)


def _dciodvfy(path: Path) -> list[str]:
    """dciodvfy's (dicom3tools) error lines for one file: the standard's IOD checker."""
    exe = shutil.which("dciodvfy")
    assert exe is not None, "dciodvfy not found: install dicom3tools (make system-deps)"
    run = subprocess.run([exe, str(path)], capture_output=True, text=True, timeout=60)
    return [line for line in (run.stdout + run.stderr).splitlines() if line.startswith("Error")]


def test_written_ct_passes_dciodvfy(tmp_path: Path) -> None:
    aff = affine((0.3, 0.8, 1.7), rot=ROT, origin_lps=(5.5, -7.25, 100.0))
    w = write_series(tmp_path / "s", linear_hu((3, 6, 5)), aff, slice_thickness_mm=1.7)
    for path in w.paths:
        assert _dciodvfy(path) == [], path
    ds = pydicom.dcmread(w.paths[0])
    for keyword in ("PatientBirthDate", "StudyDate", "StudyID", "PatientPosition", "KVP"):
        assert keyword in ds and ds[keyword].value in (None, "")  # present, empty: unknown


def test_bundled_demo_passes_dciodvfy() -> None:
    files = sorted((ASSETS / "demo" / "ct").glob("*.dcm"))
    assert len(files) == 80
    for path in files[:: len(files) // 8]:
        assert _dciodvfy(path) == [], path
