"""The fast header reader agrees with pydicom on every file, or steps aside."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from pydicom.data import get_testdata_file
from pydicom.dataset import Dataset
from pydicom.uid import ImplicitVRLittleEndian

from ctdrill.imaging.dicom.discovery import Skipped, read_headers
from ctdrill.imaging.dicom.fastheader import HeaderCorruptError, read_fast_header
from tests.imaging.factory import affine, linear_hu, write


def _as_plain(got: object) -> object:
    if isinstance(got, list):
        return [dataclasses.asdict(h) for h in got]
    return got


def _agree(path: Path) -> None:
    for ct_only in (True, False):
        fast = read_headers(path, ct_only=ct_only, fast=True)
        slow = read_headers(path, ct_only=ct_only, fast=False)
        assert _as_plain(fast) == _as_plain(slow), path


def test_identical_headers_on_every_real_file(shared_data: Path) -> None:
    files = [p for p in sorted(shared_data.rglob("*")) if p.is_file()]
    assert len(files) > 150
    for path in files:
        _agree(path)


@pytest.mark.parametrize(
    "name", ["CT_small.dcm", "693_UNCR.dcm", "693_J2KR.dcm", "MR_small.dcm", "SC_rgb.dcm"]
)
def test_identical_headers_on_pydicom_files(name: str) -> None:
    _agree(Path(str(get_testdata_file(name))))


def test_nested_undefined_length_sequences_are_skipped(tmp_path: Path) -> None:
    inner = Dataset()
    inner.CodeValue = "X"
    item = Dataset()
    item.ReferencedSOPInstanceUID = "1.2.3"
    item.PurposeOfReferenceCodeSequence = [inner]
    for ts in ("1.2.840.10008.1.2.1", ImplicitVRLittleEndian):
        w = write(
            tmp_path / ts,
            linear_hu((2, 3, 4)),
            affine(),
            transfer_syntax=ts,
            extra={"ReferencedImageSequence": [item, item], "SourceImageSequence": [item]},
        )
        got = read_fast_header(w.paths[0])
        assert got is not None
        assert got.transfer_syntax == ts and got.implicit == (ts == ImplicitVRLittleEndian)
        assert got.has_pixels and got.pixel_length == 24
        assert got.tags["Rows"] == 3 and got.tags["Columns"] == 4
        offset = got.pixel_offset
        raw = w.paths[0].read_bytes()
        assert offset is not None
        np.testing.assert_array_equal(
            np.frombuffer(raw[offset : offset + 24], "<i2").reshape(3, 4), linear_hu((2, 3, 4))[0]
        )
        _agree(w.paths[0])


def test_truncated_files_are_corrupt_and_foreign_ones_fall_back(tmp_path: Path) -> None:
    w = write(tmp_path / "s", linear_hu((1, 3, 4)), affine())
    raw = w.paths[0].read_bytes()
    cut = tmp_path / "cut.dcm"
    cut.write_bytes(raw[:300])
    with pytest.raises(HeaderCorruptError):
        read_fast_header(cut)
    skipped = read_headers(cut)
    assert isinstance(skipped, Skipped) and "corrupt DICOM header" in skipped.reason
    # A header element declaring 4 GB in a small file: refused without reading it.
    bomb = bytearray(raw)
    at = bomb.find(b"\x28\x00\x30\x00DS")  # PixelSpacing
    bomb[at + 4 : at + 8] = b"UT\x00\x00"
    bomb[at + 8 : at + 8] = b"\xf0\xff\xff\xff"
    (tmp_path / "bomb.dcm").write_bytes(bytes(bomb))
    with pytest.raises(HeaderCorruptError):
        read_fast_header(tmp_path / "bomb.dcm")
    # Not little endian / unknown layout: None, and pydicom decides.
    junk = tmp_path / "junk.bin"
    junk.write_bytes(bytes(128) + b"DICM" + b"\xff" * 40)
    assert read_fast_header(junk) is None
    assert read_headers(junk) is not None  # a Skipped or planes from pydicom, not a crash


def test_headers_longer_than_the_first_read(tmp_path: Path) -> None:
    hu = linear_hu((2, 3, 4))
    items = []
    for n in range(1500):
        item = Dataset()
        item.ReferencedSOPClassUID = "1.2.840.10008.5.1.4.1.1.2"
        item.ReferencedSOPInstanceUID = f"1.2.3.4.5.6.7.8.9.{n}"
        items.append(item)
    w = write(tmp_path, hu, affine(), extra={"ReferencedImageSequence": items})
    got = read_fast_header(w.paths[0])
    assert got is not None and got.pixel_offset is not None and got.pixel_offset > 65536
    assert got.tags["Rows"] == 3 and got.tags["RescaleSlope"] == "1"
    _agree(w.paths[0])
