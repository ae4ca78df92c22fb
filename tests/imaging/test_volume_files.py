"""CT volumes from NIfTI, NRRD and MetaImage files: exact voxels, exact geometry, HU or not.

Each file is written by the format's own library (nibabel, pynrrd, SimpleITK) and read by
``load_ct``; the voxels must equal what was written and every voxel corner must sit where
SimpleITK and nibabel put it, to 1e-6 mm (float32 header fields included: the reference reads
the same rounded numbers).
"""

from __future__ import annotations

import struct
from pathlib import Path

import nibabel
import numpy as np
import pytest

from ctdrill.imaging import load_ct
from ctdrill.imaging.volumes.identity import CONTENT_UID_PREFIX
from ctdrill.imaging.volumes.load import hu_problem
from ctdrill.imaging.volumes.types import VolumeFileError
from tests.imaging.volume_writers import (
    FLIP,
    corners_lps,
    every_corner_ijk,
    oblique_affine,
    ramp,
    sitk_corners_lps,
    sitk_voxels,
    write_mha,
    write_nifti,
    write_nrrd,
)

SHAPE = (5, 6, 7)  # (k, j, i)
CORNER_TOL_MM = 1e-6
AFFINE = oblique_affine()

WRITERS = {
    "nii": lambda p, d, a: write_nifti(p / "ct.nii", d, a),
    "nii.gz": lambda p, d, a: write_nifti(p / "ct.nii.gz", d, a),
    "nii-big-endian": lambda p, d, a: write_nifti(p / "ct1.nii", d, a, endian=">"),
    "nrrd-gzip": lambda p, d, a: write_nrrd(p / "ct.nrrd", d, a),
    "nrrd-raw-ras": lambda p, d, a: write_nrrd(
        p / "ct.nrrd", d, a, encoding="raw", space="right-anterior-superior"
    ),
    "nrrd-bzip2": lambda p, d, a: write_nrrd(p / "ct.nrrd", d, a, encoding="bzip2"),
    "nhdr-detached": lambda p, d, a: write_nrrd(p / "ct.nhdr", d, a, detached=True),
    "mha": lambda p, d, a: write_mha(p / "ct.mha", d, a),
    "mha-zlib": lambda p, d, a: write_mha(p / "ct.mha", d, a, compress=True),
    "mhd-raw": lambda p, d, a: write_mha(p / "ct.mhd", d, a),
}


#: Files whose voxels SimpleITK 2.5 does not read (no bzip2 in its NrrdIO; it reads the
#: header, and ctdrill refuses the file unless ITK's grid is its own): checked against the
#: written grid.
NOT_BY_SIMPLEITK = ("nrrd-bzip2",)


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_voxels_and_every_corner_agree_with_simpleitk(tmp_path: Path, kind: str) -> None:
    data = ramp(SHAPE)
    path = WRITERS[kind](tmp_path, data, AFFINE)
    volume = load_ct(path)
    np.testing.assert_array_equal(volume.hu, data)
    assert volume.hu.dtype == np.int16
    ijk = every_corner_ijk(SHAPE)
    ours = corners_lps(volume.affine_lps, ijk)
    if kind not in NOT_BY_SIMPLEITK:
        np.testing.assert_array_equal(volume.hu, sitk_voxels(path))
        np.testing.assert_allclose(ours, sitk_corners_lps(path, ijk), rtol=0, atol=CORNER_TOL_MM)
    # and where they were written (float32 NIfTI fields round at ~1e-6 of a value)
    np.testing.assert_allclose(ours, corners_lps(AFFINE, ijk), rtol=0, atol=2e-5)
    # the grid's 0.75-1.25 mm voxels are coarse for implant planning (the DICOM loader's rule)
    assert volume.info.is_hu and volume.warning_codes == ("coarse_voxels",)
    assert volume.info.series_uid.startswith(CONTENT_UID_PREFIX)


def test_nifti2_is_refused_because_itk_cannot_read_it(tmp_path: Path) -> None:
    # SimpleITK 2.5 (hence 3D Slicer's reader) reads no NIfTI-2 header: nobody could check
    # where ctdrill puts the voxels
    for endian in "<>":
        path = write_nifti(tmp_path / "ct.nii.gz", ramp(SHAPE), AFFINE, version=2, endian=endian)
        with pytest.raises(
            VolumeFileError, match=r"ct\.nii\.gz: ITK .*refuses the header.*NIfTI-1"
        ):
            load_ct(path)


@pytest.mark.parametrize("version", [1])
def test_nifti_corners_agree_with_nibabel(tmp_path: Path, version: int) -> None:
    path = write_nifti(tmp_path / "ct.nii.gz", ramp(SHAPE), AFFINE, version=version)
    volume = load_ct(path)
    ras = nibabel.load(str(path)).affine
    ijk = every_corner_ijk(SHAPE)
    np.testing.assert_allclose(
        corners_lps(volume.affine_lps, ijk), corners_lps(FLIP @ ras, ijk), rtol=0, atol=1e-9
    )
    assert volume.info.source_format == f"NIfTI-{version}"


def test_the_name_does_not_decide_the_format(tmp_path: Path) -> None:
    data = ramp(SHAPE)
    nii = write_nifti(tmp_path / "a.nii.gz", data, AFFINE)
    nrrd_file = write_nrrd(tmp_path / "b.nrrd", data, AFFINE)
    mha = write_mha(tmp_path / "c.mha", data, AFFINE)
    for src, name in ((nii, "scan.mha"), (nrrd_file, "scan.nii"), (mha, "scan.dat")):
        moved = src.rename(tmp_path / name)
        np.testing.assert_array_equal(load_ct(moved).hu, data)
        moved.rename(src)
    (tmp_path / "notes.nii").write_text("not a volume\n")
    with pytest.raises(VolumeFileError, match=r"notes.nii: not a DICOM, NIfTI, NRRD or Meta"):
        load_ct(tmp_path / "notes.nii")


def test_one_volume_one_identity_whatever_the_format(tmp_path: Path) -> None:
    # Geometry exact in float32 (NIfTI's storage), so every format holds the same numbers.
    affine = np.diag([0.5, 0.25, 1.0, 1.0])
    affine[:3, 3] = [-12.5, 30.0, -7.75]
    data = ramp(SHAPE)
    uids = {
        load_ct(write(tmp_path, data, affine)).info.series_uid
        for name, write in WRITERS.items()
        if not name.startswith("nrrd-raw")  # one writer per file name is enough
    }
    assert len(uids) == 1
    other = data.copy()
    other[2, 3, 4] += 1
    assert load_ct(write_nrrd(tmp_path / "x.nrrd", other, affine)).info.series_uid not in uids


def test_scaling_is_applied_exactly(tmp_path: Path) -> None:
    stored = (ramp(SHAPE, np.uint16, lo=0) * 7).astype(np.uint16)
    v = load_ct(write_nifti(tmp_path / "a.nii", stored, AFFINE, slope=1.0, inter=-1024.0))
    assert v.hu.dtype == np.int16
    np.testing.assert_array_equal(v.hu, stored.astype(np.int64) - 1024)
    assert v.info.rescale_type == "scl_slope/scl_inter" and v.info.is_hu
    v = load_ct(write_nifti(tmp_path / "b.nii", stored, AFFINE, slope=0.5, inter=-1000.0))
    assert v.hu.dtype == np.float32
    np.testing.assert_array_equal(v.hu, stored * 0.5 - 1000.0)
    # scl_slope 0 (or NaN) means no scaling, by the NIfTI rule (bytes 112 and 116)
    path = write_nifti(tmp_path / "c.nii", ramp(SHAPE), AFFINE)
    for slope in (0.0, float("nan")):
        raw = bytearray(path.read_bytes())
        struct.pack_into("<ff", raw, 112, slope, 5.0)
        path.write_bytes(bytes(raw))
        np.testing.assert_array_equal(load_ct(path).hu, ramp(SHAPE))


@pytest.mark.parametrize(
    ("values", "reason"),
    [
        (np.linspace(0, 4095, 210).astype(np.uint16), "never go below 0"),
        (np.linspace(0.0, 1.0, 210).astype(np.float32), "never go below 0"),
        (np.linspace(-1.0, 1.0, 210).astype(np.float32), "normalised intensities"),
        (np.linspace(3, 60000, 210).astype(np.uint16), "never go below 0"),
    ],
    ids=["grey-0-4095", "float-0-1", "float-minus1-1", "cbct-uint16"],
)
def test_values_that_cannot_be_hu_are_flagged(
    tmp_path: Path, values: np.ndarray, reason: str
) -> None:
    v = load_ct(write_nrrd(tmp_path / "g.nrrd", values.reshape(SHAPE), AFFINE))
    assert not v.info.is_hu
    (w,) = [w for w in v.warnings if w.code == "not_hu"]
    assert reason in w.message and "--grey-to-hu" in w.message


def test_hu_rule() -> None:
    assert hu_problem(-1024.0, 3000.0) is None
    assert hu_problem(-150.0, 1500.0) is None  # a crop inside the head: fat, no air
    assert hu_problem(0.0, 4095.0) is not None
    assert hu_problem(-0.5, 0.5) is not None
    # grey values whose air reads near 0, a few noise or padding voxels below it: not HU
    assert hu_problem(-30.0, 4095.0, low_tail=-2.0) is not None
    assert hu_problem(-1024.0, 3000.0, low_tail=-1000.0) is None
    assert hu_problem(-150.0, 1500.0, low_tail=-120.0) is None  # fat, no air: HU


def test_grey_values_with_air_near_zero_and_noise_below_it_are_flagged(tmp_path: Path) -> None:
    """0..4095 grey values (air about 0) with 0.05 % noise and padding voxels down to -30."""
    rng = np.random.default_rng(3)
    grey = rng.integers(0, 4096, size=SHAPE).astype(np.int16)
    flat = grey.reshape(-1)
    flat[rng.choice(flat.size, size=max(1, flat.size // 2000), replace=False)] = -30
    v = load_ct(write_nrrd(tmp_path / "g.nrrd", grey, AFFINE))
    (w,) = [w for w in v.warnings if w.code == "not_hu"]
    assert not v.info.is_hu and "air near 0" in w.message and "--grey-to-hu" in w.message
    hu = grey.copy()
    hu.reshape(-1)[: flat.size // 100] = -1000  # 1 % air at -1000: HU
    assert load_ct(write_nrrd(tmp_path / "h.nrrd", hu, AFFINE)).info.is_hu


def test_non_finite_voxels_are_masked_invalid(tmp_path: Path) -> None:
    data = ramp(SHAPE).astype(np.float32)
    data[1, 2, 3] = np.nan
    data[4, 5, 6] = np.inf
    v = load_ct(write_nrrd(tmp_path / "nan.nrrd", data, AFFINE))
    assert v.valid is not None and int((~v.valid).sum()) == 2 and not v.valid[1, 2, 3]
    assert "padding" in v.warning_codes
    assert np.isfinite(v.sample(corners_lps(AFFINE, every_corner_ijk(SHAPE)))).all()


def test_qform_and_sform(tmp_path: Path) -> None:
    data = ramp(SHAPE)
    moved = AFFINE.copy()
    moved[:3, 3] += [0.0, 0.0, 3.0]
    path = write_nifti(tmp_path / "two.nii", data, AFFINE, qform_lps=moved)
    v = load_ct(path)
    (w,) = [w for w in v.warnings if w.code == "qform_sform_differ"]
    assert "3 mm apart" in w.message and "sform is used" in w.message
    np.testing.assert_allclose(v.affine_lps, FLIP @ nibabel.load(str(path)).affine, atol=1e-9)
    # only the qform coded: the qform
    v = load_ct(write_nifti(tmp_path / "q.nii", data, AFFINE, sform_code=0, qform_lps=moved))
    np.testing.assert_allclose(v.affine_lps, moved, atol=2e-5)
    assert v.warning_codes == ("coarse_voxels",)
    with pytest.raises(VolumeFileError, match="qform_code and sform_code are both 0"):
        load_ct(write_nifti(tmp_path / "none.nii", data, AFFINE, sform_code=0, qform_code=0))


def test_units_and_tilt(tmp_path: Path) -> None:
    import nibabel as nb

    data = ramp(SHAPE)
    sheared = AFFINE.copy()
    sheared[:3, 2] = AFFINE[:3, 2] + 0.2 * AFFINE[:3, 0]  # a gantry tilt's shear
    # a NRRD holds the shear and ITK reads it so: kept exact
    v = load_ct(write_nrrd(tmp_path / "tilt.nrrd", data, sheared))
    assert "gantry_tilt" in v.warning_codes and v.info.gantry_tilt_deg > 5
    np.testing.assert_allclose(v.affine_lps, sheared, atol=1e-9)
    ijk = every_corner_ijk(SHAPE)
    np.testing.assert_allclose(
        corners_lps(v.affine_lps, ijk),
        sitk_corners_lps(tmp_path / "tilt.nrrd", ijk),
        rtol=0,
        atol=CORNER_TOL_MM,
    )
    # a NIfTI sform cannot: ITK refuses it (no orthonormal directions), so does ctdrill
    path = write_nifti(tmp_path / "tilt.nii", data, sheared, qform_code=0)
    with pytest.raises(VolumeFileError, match=r"tilt\.nii: ITK .*refuses.*orthonormal"):
        load_ct(path)
    path = write_nifti(tmp_path / "plain.nii", data, AFFINE, qform_code=0)
    v = load_ct(path)
    img = nb.load(str(path))
    in_metres = img.affine.copy()
    in_metres[:3] /= 1000.0
    out = nb.Nifti1Image(np.asarray(img.dataobj), in_metres, header=img.header)
    out.set_sform(in_metres, code=1)
    out.header.set_xyzt_units("meter")
    metres = tmp_path / "m.nii"
    nb.save(out, str(metres))
    np.testing.assert_allclose(load_ct(metres).affine_lps, v.affine_lps, atol=1e-6)


def test_series_option_must_name_the_file(tmp_path: Path) -> None:
    path = write_mha(tmp_path / "a.mha", ramp(SHAPE), AFFINE)
    uid = load_ct(path).info.series_uid
    from ctdrill.imaging.dicom.identity import series_label

    assert load_ct(path, series_uid=series_label(uid)).info.series_uid == uid
    with pytest.raises(VolumeFileError, match="the file holds one volume"):
        load_ct(path, series_uid="0123456789ab")


def test_a_folder_holding_a_volume_file_says_so(tmp_path: Path) -> None:
    write_nifti(tmp_path / "ct.nii.gz", ramp(SHAPE), AFFINE)
    with pytest.raises(
        VolumeFileError, match=r"no CT image series.*holds ct\.nii\.gz: give the file"
    ):
        load_ct(tmp_path)


def test_files_read_name_a_detached_data_file(tmp_path: Path) -> None:
    from ctdrill.imaging.volumes.sniff import files_read

    nhdr = write_nrrd(tmp_path / "a.nhdr", ramp(SHAPE), AFFINE, detached=True)
    mhd = write_mha(tmp_path / "b.mhd", ramp(SHAPE), AFFINE)
    nii = write_nifti(tmp_path / "c.nii", ramp(SHAPE), AFFINE)
    assert [p.name for p in files_read(nhdr, error=VolumeFileError)] == ["a.nhdr", "a.raw.gz"]
    assert [p.name for p in files_read(mhd, error=VolumeFileError)] == ["b.mhd", "b.raw"]
    assert files_read(nii, error=VolumeFileError) == (nii,)


def test_a_metaimage_label_map_is_a_plan_input(tmp_path: Path) -> None:
    import json

    from ctdrill.imaging.plan.landmarks import MaskLandmark
    from ctdrill.imaging.plan.load import load_plan_set

    labels = np.zeros(SHAPE, dtype=np.uint8)
    labels[1:3, 2, 1:6] = 3  # a ToothFairy2-style left-canal label
    write_mha(tmp_path / "labels.mha", labels, AFFINE, compress=True)
    plan = tmp_path / "plan.json"
    plan.write_text(
        json.dumps({"format": "ctdrill-plan/1", "entry_mm": [0, 0, 10], "target_mm": [0, 0, 0]})
    )
    (p,) = load_plan_set([plan, tmp_path / "labels.mha"])
    (lm,) = p.landmarks
    assert isinstance(lm, MaskLandmark) and lm.name == "labels label 3" and lm.label == 3
    np.testing.assert_array_equal(lm.mask, labels == 3)
    np.testing.assert_allclose(lm.affine_lps, AFFINE, atol=1e-12)


def test_a_grey_map_on_a_file_in_hu_names_the_file_type_not_a_rescale_type(
    tmp_path: Path,
) -> None:
    from ctdrill.imaging.dicom.grey import GreyToHu, apply_grey_map

    hu = np.linspace(-1000, 1500, 210).astype(np.int16).reshape(SHAPE)
    v = load_ct(write_nrrd(tmp_path / "hu.nrrd", hu, AFFINE))
    assert v.info.is_hu
    mapped = apply_grey_map(v, GreyToHu(1.0, 0.0, None, "given"))
    (w,) = [w for w in mapped.warnings if w.code == "grey_map_on_hu"]
    assert "a NRRD file whose values read as HU" in w.message and "RescaleType" not in w.message


def _identity_by_hand(data: np.ndarray, affine_lps: np.ndarray) -> str:
    """The identity's definition written out: hashlib over the header text, the affine and
    the voxels' little-endian bytes."""
    import hashlib

    h = hashlib.sha256(b"ctdrill-volume/1\0" + repr(data.shape).encode() + b"\0int16")
    h.update(np.asarray(affine_lps, dtype="<f8").tobytes() + data.astype("<i2").tobytes())
    return "sha256:" + h.hexdigest()


def _nifti(path: Path, data: np.ndarray, affine: np.ndarray) -> Path:
    """``data`` as ``path`` (.nii, or .nii.gz compressed at level 1: fast to write)."""
    import gzip

    raw = write_nifti(path.with_suffix(".raw.nii"), data, affine)
    if path.name.endswith(".gz"):
        path.write_bytes(gzip.compress(raw.read_bytes(), compresslevel=1))
        return path
    return raw.rename(path)


@pytest.mark.parametrize(("name", "slices"), [("ct.nii", 40), ("ct.nii.gz", 8)])
def test_the_identity_hashed_while_reading_is_the_definition(
    tmp_path: Path, name: str, slices: int
) -> None:
    # raw: 40 x 512 x 520 int16 (21 MB), more than one 16 MiB read; gzip: 1 MiB inflate steps
    plane = np.random.default_rng(5).integers(-1000, 2000, size=(512, 520), dtype=np.int16)
    data = plane[None] + np.arange(slices, dtype=np.int16)[:, None, None]
    affine = np.diag([0.5, 0.25, 1.0, 1.0])
    affine[:3, 3] = [-12.5, 30.0, -7.75]
    volume = load_ct(_nifti(tmp_path / name, data, affine))
    assert volume.info.series_uid == _identity_by_hand(data, volume.affine_lps)
    data[-1, 511, 519] += 1  # the last voxel
    changed = load_ct(_nifti(tmp_path / ("x" + name), data, affine))
    assert changed.info.series_uid == _identity_by_hand(data, volume.affine_lps)
    assert changed.info.series_uid != volume.info.series_uid


def test_a_digest_fed_short_refuses_to_name_the_volume() -> None:
    from ctdrill.imaging.volumes.identity import VoxelDigest

    with VoxelDigest((2, 2, 2), np.eye(4)) as digest:
        digest.feed(memoryview(bytes(14)))
        with pytest.raises(ValueError, match="fed 14 voxel bytes of 16"):
            digest.uid()
