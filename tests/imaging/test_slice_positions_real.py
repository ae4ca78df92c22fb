"""Every slice where its header says it is: real series against per-slice IPP read with pydicom,
and SimpleITK as a peer where it can represent the stack (regular, untilted)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pydicom
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging import CTVolume, load_series

GE_HEAD = "dcmqa_ct_GE_head_gantrytilt_varspacing"
SERIES = (
    GE_HEAD,
    "dcmqa_ct_Philips_phantom_gantrytilt_mixedfolder",
    "dcmqa_ct_Philips_phantom_notilt_5mm",
    "dcmqi_ct_3slice_GE_abdomen",
)


def _header_planes(folder: Path, series_uid: str) -> list[tuple[np.ndarray, np.ndarray, tuple]]:
    """(IPP, IOP, PixelSpacing) of every image plane of the series, straight from the headers."""
    planes = []
    for f in sorted(p for p in folder.rglob("*") if p.is_file()):
        try:
            ds = pydicom.dcmread(f, stop_before_pixels=True)
        except pydicom.errors.InvalidDicomError:
            continue
        if str(ds.get("SeriesInstanceUID", "")) != series_uid:
            continue
        if "ImagePositionPatient" not in ds or "LOCALIZER" in list(ds.get("ImageType", [])):
            continue
        planes.append(
            (
                np.array([float(x) for x in ds.ImagePositionPatient]),
                np.array([float(x) for x in ds.ImageOrientationPatient]),
                tuple(float(x) for x in ds.PixelSpacing),
            )
        )
    return planes


def _truth(volume: CTVolume, folder: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-slice IPP (ordered along the IOP normal), the column step and the row step, LPS mm."""
    planes = _header_planes(folder, volume.info.series_uid)
    iop = planes[0][1]
    row_dir, col_dir = iop[:3], iop[3:]
    normal = np.cross(row_dir, col_dir)
    ipp = np.array([p[0] for p in planes])
    ipp = ipp[np.argsort(ipp @ normal)]
    row_sp, col_sp = planes[0][2]
    return ipp, row_dir * col_sp, col_dir * row_sp


@pytest.mark.parametrize("name", SERIES)
def test_every_voxel_is_where_its_header_puts_it(shared_data: Path, name: str) -> None:
    folder = shared_data / name
    v = load_series(folder)
    ipp, di, dj = _truth(v, folder)
    assert ipp.shape == (v.hu.shape[0], 3)
    np.testing.assert_allclose(v.slice_origins_lps, ipp, rtol=0, atol=1e-6)
    rng = np.random.default_rng(14)
    n_s, n_r, n_c = v.hu.shape
    k = rng.integers(0, n_s, 40)
    j = rng.integers(0, n_r, 40)
    i = rng.integers(0, n_c, 40)
    truth_lps = ipp[k] + i[:, None] * di + j[:, None] * dj
    ijk = np.stack([i, j, k], axis=1).astype(float)
    # The headers' IOP carry ~6 digits and are not exactly orthonormal; the loader makes them
    # so, which moves a far corner by ~1e-5 mm.
    np.testing.assert_allclose(v.index_to_lps(ijk), truth_lps, rtol=0, atol=1e-4)
    np.testing.assert_allclose(v.lps_to_index(truth_lps), ijk, rtol=0, atol=1e-4)
    # Sampling at the header's voxel centre returns the stored value (padding: outside_hu), up
    # to that 1e-4 voxel times the local HU gradient.
    got = v.sample(truth_lps, outside_hu=-4321.0)
    stored = v.hu[k, j, i].astype(float)
    if v.valid is not None:
        stored = np.where(v.valid[k, j, i], stored, -4321.0)
    np.testing.assert_allclose(got, stored, rtol=0, atol=0.5)
    # Half-way between two real neighbouring slices: their mean, whatever the step.
    mid_lps = 0.5 * (ipp[:-1] + ipp[1:])
    want = 0.5 * (v.hu[:-1, 0, 0].astype(float) + v.hu[1:, 0, 0].astype(float))
    if v.valid is None:
        np.testing.assert_allclose(v.sample(mid_lps), want, rtol=0, atol=1e-6)


def test_the_ge_head_is_irregular_and_says_so(shared_data: Path) -> None:
    v = load_series(shared_data / GE_HEAD)
    ipp, _, _ = _truth(v, shared_data / GE_HEAD)
    assert not v.regular
    # A median-step affine misplaces most of its slices (the 7 mm part by up to 38 mm).
    a = np.asarray(v.affine_lps)
    median_affine = a[:3, 3] + np.arange(len(ipp))[:, None] * a[:3, 2]
    miss = np.linalg.norm(median_affine - ipp, axis=1)
    assert miss.max() > 30.0 and np.count_nonzero(miss > 1.0) >= 13


def test_inspect_json_states_no_wrong_affine(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["inspect", "--json", str(shared_data / GE_HEAD)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["regular"] is False and doc["affine_lps"] is None
    assert doc["affine_residual_mm"] > 30.0
    ipp, di, dj = _truth(load_series(shared_data / GE_HEAD), shared_data / GE_HEAD)
    np.testing.assert_allclose(doc["slice_origins_lps"], ipp, rtol=0, atol=1e-6)
    np.testing.assert_allclose(doc["voxel_axes_lps"], [di, dj], rtol=0, atol=1e-6)
    # a regular stack keeps its affine, and the per-slice keys agree with it
    assert main(["inspect", "--json", str(shared_data / SERIES[2])]) == 0
    doc = json.loads(capsys.readouterr().out)
    aff = np.array(doc["affine_lps"])
    assert doc["regular"] is True and aff.shape == (4, 4)
    k = np.arange(len(doc["slice_origins_lps"]))
    np.testing.assert_allclose(
        doc["slice_origins_lps"], aff[:3, 3] + k[:, None] * aff[:3, 2], atol=1e-9
    )
    assert main(["inspect", str(shared_data / GE_HEAD)]) == 0
    assert "affine_lps none: irregular slice positions" in capsys.readouterr().out


def test_simpleitk_agrees_on_a_regular_untilted_series(shared_data: Path, tmp_path: Path) -> None:
    sitk = pytest.importorskip("SimpleITK")
    folder = shared_data / "dcmqa_ct_Philips_phantom_notilt_5mm"
    v = load_series(folder)
    reader = sitk.ImageSeriesReader()
    files = reader.GetGDCMSeriesFileNames(str(folder), v.info.series_uid)
    # copy so that SimpleITK reads exactly these files
    for f in files:
        shutil.copy(f, tmp_path / Path(f).name)
    reader.SetFileNames(reader.GetGDCMSeriesFileNames(str(tmp_path), v.info.series_uid))
    image = reader.Execute()
    rng = np.random.default_rng(5)
    for _ in range(20):
        ijk = (int(rng.integers(0, v.dims[0])), int(rng.integers(0, v.dims[1])))
        k = int(rng.integers(0, v.dims[2]))
        peer = np.array(image.TransformIndexToPhysicalPoint((*ijk, k)))
        ours = v.index_to_lps(np.array([*ijk, k], dtype=float))
        np.testing.assert_allclose(ours, peer, rtol=0, atol=1e-4)
