"""Compressed syntaxes: which pinned plugin decodes each, and that it decodes exactly."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pydicom
import pytest
from pydicom.data import get_testdata_file
from pydicom.pixels import get_decoder

import ctdrill.imaging.dicom.pixels as pixels
from ctdrill.imaging import load_series
from ctdrill.imaging.dicom.discovery import read_headers
from ctdrill.imaging.dicom.pixels import decoder_plugin_for, read_stored


def _path(name: str) -> Path:
    found = get_testdata_file(name)
    assert found is not None, f"pydicom test file {name} missing (install pydicom-data)"
    return Path(str(found))


def _stored(name: str) -> np.ndarray:
    got = read_headers(_path(name), ct_only=False)
    assert isinstance(got, list)
    return read_stored(got[0])


# (file, uncompressed reference, pylibjpeg plugin module that must do the work)
CASES = [
    ("693_J2KR.dcm", "693_UNCR.dcm", "openjpeg"),
    ("MR_small_RLE.dcm", "MR_small.dcm", "rle"),
    ("MR_small_jpeg_ls_lossless.dcm", "MR_small.dcm", "libjpeg"),
    ("JPEG-LL.dcm", None, "libjpeg"),
]


@pytest.mark.parametrize(("name", "reference", "module"), CASES)
def test_each_syntax_is_decoded_by_the_pinned_plugin(
    name: str, reference: str | None, module: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    import pylibjpeg.utils

    ts = pydicom.dcmread(_path(name), stop_before_pixels=True).file_meta.TransferSyntaxUID
    assert decoder_plugin_for(ts) == "pylibjpeg"
    assert pylibjpeg.utils.get_pixel_data_decoders()[ts].__module__.split(".")[0] == module
    # read_stored asks pydicom for exactly that plugin (never Pillow, which vtk pulls in).
    seen: list[str] = []
    real_get_decoder = pixels.get_decoder

    class Spy:
        def __init__(self, uid: str) -> None:
            self._decoder = real_get_decoder(uid)
            self.available_plugins = self._decoder.available_plugins

        def as_array(self, *args: Any, **kwargs: Any) -> Any:
            seen.append(kwargs["decoding_plugin"])
            return self._decoder.as_array(*args, **kwargs)

    monkeypatch.setattr(pixels, "get_decoder", Spy)
    got = _stored(name)
    assert seen == ["pylibjpeg"]
    if reference is not None:
        np.testing.assert_array_equal(got, _stored(reference))
    else:
        ds = pydicom.dcmread(_path(name))
        ds.pixel_array_options(decoding_plugin="pylibjpeg")
        np.testing.assert_array_equal(got, ds.pixel_array)


def test_pillow_would_otherwise_be_a_candidate_for_jpeg2000() -> None:
    # Why the plugin is pinned: pydicom lists Pillow first for JPEG 2000 when it is importable.
    plugins = get_decoder(pydicom.uid.JPEG2000Lossless).available_plugins
    assert "pylibjpeg" in plugins
    assert decoder_plugin_for(pydicom.uid.JPEG2000Lossless) == "pylibjpeg"
    assert decoder_plugin_for(pydicom.uid.ExplicitVRLittleEndian) == ""


def test_ct_small_loads_as_one_slice() -> None:
    path = _path("CT_small.dcm")
    v = load_series(path)
    ds = pydicom.dcmread(path)
    expected = ds.pixel_array.astype(float) * float(ds.RescaleSlope) + float(ds.RescaleIntercept)
    np.testing.assert_array_equal(v.hu[0], expected)
    assert v.warning_codes == ("single_slice", "coarse_voxels")  # 5 mm thick
    np.testing.assert_allclose(v.affine_lps[:3, 3], [float(x) for x in ds.ImagePositionPatient])


def test_jpeg2000_lossless_ct_equals_uncompressed_and_lossy_is_flagged() -> None:
    unc = load_series(_path("693_UNCR.dcm"))
    j2k = load_series(_path("693_J2KR.dcm"))
    np.testing.assert_array_equal(j2k.hu, unc.hu)
    assert j2k.valid is not None and unc.valid is not None
    np.testing.assert_array_equal(j2k.valid, unc.valid)
    assert "padding" in j2k.warning_codes and "lossy_compression" not in j2k.warning_codes
    lossy = load_series(_path("693_J2KI.dcm"))
    assert "lossy_compression" in lossy.warning_codes
