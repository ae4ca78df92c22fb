"""Segmentations as landmarks: real files written by pynrrd, nibabel and highdicom; exact geometry.

Every file is built by the format's own library with a known voxel-to-world matrix, and the
landmark's LPS affine and mask are checked against it exactly (voxel centres in LPS).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import nibabel
import nrrd
import numpy as np
import pydicom
import pytest

from ctdrill.imaging.plan.labels import MAX_MASK_BYTES
from ctdrill.imaging.plan.landmarks import LandmarkInputError, MaskLandmark
from ctdrill.imaging.plan.load import load_plan, load_plan_set
from ctdrill.imaging.plan.segmentation import read_npy
from ctdrill.imaging.plan.types import PlanInputError
from ctdrill.imaging.plan.write import save_plan
from ctdrill.warning_codes import LoadWarning
from tests.conftest import ASSETS

#: A rotated (axes permuted and flipped), anisotropic grid (LPS): columns are the i, j, k
#: directions. Every number is exact in binary floating point (NIfTI stores float32, DICOM
#: decimal strings), so the geometry is compared exactly.
ROT = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], np.cross([0, 1, 0], [0, 0, -1])])
SPACING = np.array([0.75, 0.875, 1.25])
ORIGIN_LPS = np.array([12.5, -30.25, -41.0])
AFFINE_LPS = np.eye(4)
AFFINE_LPS[:3, :3] = ROT * SPACING
AFFINE_LPS[:3, 3] = ORIGIN_LPS
FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])


def _labels_kji() -> np.ndarray:
    """A labelmap (k, j, i) of shape (5, 6, 7): label 2 a bar, label 5 one voxel."""
    lab = np.zeros((5, 6, 7), dtype=np.uint8)
    lab[1:3, 2, 1:6] = 2
    lab[4, 5, 6] = 5
    return lab


def _centres(mask_kji: np.ndarray, affine: np.ndarray) -> np.ndarray:
    kji = np.argwhere(mask_kji)
    ijk1 = np.column_stack([kji[:, 2], kji[:, 1], kji[:, 0], np.ones(len(kji))])
    out: np.ndarray = (ijk1 @ affine.T)[:, :3]
    return out


def _plan_with(tmp_path: Path, landmark: dict[str, object]) -> Path:
    doc = {
        "format": "ctdrill-plan/1",
        "entry_mm": [0.0, 0.0, 10.0],
        "target_mm": [0.0, 0.0, 0.0],
        "landmarks": [landmark],
    }
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(doc))
    return path


def _assert_mask(lm: object, expected_kji: np.ndarray, affine: np.ndarray) -> None:
    assert isinstance(lm, MaskLandmark) and lm.affine_lps is not None
    np.testing.assert_allclose(lm.affine_lps, affine, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(lm.mask, expected_kji)
    np.testing.assert_allclose(
        _centres(lm.mask, lm.affine_lps), _centres(expected_kji, affine), atol=1e-12
    )


@pytest.mark.parametrize("space", ["left-posterior-superior", "right-anterior-superior"])
def test_nrrd_labelmap_in_lps_or_ras(tmp_path: Path, space: str) -> None:
    lab = _labels_kji()
    world = AFFINE_LPS if space.startswith("left") else FLIP @ AFFINE_LPS
    header = {
        "space": space,
        "space directions": world[:3, :3].T,  # one row per file axis (i, j, k)
        "space origin": world[:3, 3],
        "kinds": ["domain"] * 3,
    }
    # pynrrd's default index order is Fortran: data[i, j, k].
    nrrd.write(str(tmp_path / "labels.nrrd"), lab.transpose(2, 1, 0).copy(), header)
    plan = load_plan(_plan_with(tmp_path, {"kind": "mask", "path": "labels.nrrd", "label": 2}))
    _assert_mask(plan.landmarks[0], lab == 2, AFFINE_LPS)
    # Given as a plan input, each label value is a landmark.
    (p,) = load_plan_set(
        [_plan_with(tmp_path, {"kind": "point", "point_mm": [0, 0, 0]}), tmp_path / "labels.nrrd"]
    )
    names = [lm.name for lm in p.landmarks]
    assert names == ["point 1", "labels label 2", "labels label 5"]
    _assert_mask(p.landmarks[2], lab == 5, AFFINE_LPS)


def _slicer_seg_nrrd(path: Path, layers: bool) -> tuple[np.ndarray, np.ndarray]:
    """A .seg.nrrd as 3D Slicer 5 writes it: segment fields, layers as a first list axis."""
    canal = np.zeros((5, 6, 7), dtype=bool)
    canal[1:4, 3, :] = True
    nerve = np.zeros_like(canal)
    nerve[2, 2:5, 3] = True  # overlaps the canal at (2, 3, 3) when layered
    header: dict[str, object] = {
        "space": "right-anterior-superior",
        "space origin": (FLIP @ AFFINE_LPS)[:3, 3],
        "Segment0_ID": "Segment_1",
        "Segment0_Name": "IAN canal",
        "Segment0_LabelValue": "1",
        "Segment0_Layer": "0",
        "Segment1_ID": "Segment_2",
        "Segment1_Name": "mental nerve",
        "Segment1_LabelValue": "1" if layers else "2",
        "Segment1_Layer": "1" if layers else "0",
        "Segment2_ID": "Segment_3",
        "Segment2_Name": "empty",
        "Segment2_LabelValue": "3",
        "Segment2_Layer": "0",
    }
    dirs = (FLIP @ AFFINE_LPS)[:3, :3].T
    if layers:
        data = np.stack([canal, nerve]).astype(np.uint8)  # (layer, k, j, i)
        header["kinds"] = ["list", "domain", "domain", "domain"]
        header["space directions"] = np.vstack([np.full(3, np.nan), dirs])
        fortran = data.transpose(0, 3, 2, 1).copy()  # (layer, i, j, k)
    else:
        data = (canal * 1 + (nerve & ~canal) * 2).astype(np.uint8)
        nerve = nerve & ~canal
        header["kinds"] = ["domain"] * 3
        header["space directions"] = dirs
        fortran = data.transpose(2, 1, 0).copy()
    nrrd.write(str(path), fortran, header)
    return canal, nerve


@pytest.mark.parametrize("layers", [False, True])
def test_slicer_seg_nrrd_segments_by_name(tmp_path: Path, layers: bool) -> None:
    canal, nerve = _slicer_seg_nrrd(tmp_path / "Segmentation.seg.nrrd", layers)
    lm = {"kind": "mask", "path": "Segmentation.seg.nrrd", "segment": "mental nerve"}
    plan = load_plan(_plan_with(tmp_path, lm))
    _assert_mask(plan.landmarks[0], nerve, AFFINE_LPS)
    assert plan.landmarks[0].name == "mask 1"
    # A case folder: the Line and the segmentation, each landmark named by its segment.
    case = tmp_path / "case"
    case.mkdir()
    os.replace(tmp_path / "Segmentation.seg.nrrd", case / "Segmentation.seg.nrrd")
    save_plan(
        load_plan(_plan_with(tmp_path, {"kind": "point", "point_mm": [0, 0, 0]})),
        case / "line.json",
    )
    (p,) = load_plan_set([case])
    by_name = {m.name: m for m in p.landmarks}
    _assert_mask(by_name["IAN canal"], canal, AFFINE_LPS)
    _assert_mask(by_name["mental nerve"], nerve, AFFINE_LPS)
    assert "empty" not in by_name
    assert (
        LoadWarning(
            "segment_empty", "Segmentation.seg.nrrd: segments with no voxel skipped: 'empty'"
        )
        in p.warnings
    )
    with pytest.raises(LandmarkInputError, match=r"no segment named 'nerve' \(segments: 'IAN"):
        load_plan(
            _plan_with(tmp_path, {**lm, "path": "case/Segmentation.seg.nrrd", "segment": "nerve"})
        )


def test_plan_with_segment_round_trips_through_save(tmp_path: Path) -> None:
    _slicer_seg_nrrd(tmp_path / "Segmentation.seg.nrrd", True)
    lm = {"kind": "mask", "path": "Segmentation.seg.nrrd", "segment": "IAN canal"}
    plan = load_plan(_plan_with(tmp_path, lm))
    sub = tmp_path / "elsewhere"
    sub.mkdir()
    save_plan(plan, sub / "copy.json")
    doc = json.loads((sub / "copy.json").read_text())
    assert doc["landmarks"][0] == {
        "name": "mask 1",
        "kind": "mask",
        "path": "../Segmentation.seg.nrrd",
        "segment": "IAN canal",
    }
    again = load_plan(sub / "copy.json")
    np.testing.assert_array_equal(again.landmarks[0].mask, plan.landmarks[0].mask)  # type: ignore[union-attr]


@pytest.mark.parametrize("name", ["labels.nii.gz", "labels.nii"])
def test_nifti_labelmap_ras_to_lps(tmp_path: Path, name: str) -> None:
    lab = _labels_kji()
    img = nibabel.Nifti1Image(lab.transpose(2, 1, 0).copy(), FLIP @ AFFINE_LPS)
    nibabel.save(img, str(tmp_path / name))
    plan = load_plan(_plan_with(tmp_path, {"kind": "mask", "path": name}))
    _assert_mask(plan.landmarks[0], lab != 0, AFFINE_LPS)
    with pytest.raises(LandmarkInputError, match="carries its own geometry"):
        load_plan(
            _plan_with(tmp_path, {"kind": "mask", "path": name, "affine_lps": np.eye(4).tolist()})
        )


def _dicom_seg(tmp_path: Path, *, own_grid: bool) -> tuple[Path, np.ndarray, np.ndarray]:
    """A DICOM SEG written by highdicom on the demo CT, on the CT grid or on its own."""
    import highdicom as hd
    from pydicom.sr.codedict import codes

    from ctdrill.imaging import load_series

    ct_files = sorted((ASSETS / "demo" / "ct").glob("*.dcm"))
    sources = [pydicom.dcmread(f) for f in ct_files]
    volume = load_series(ASSETS / "demo" / "ct")
    desc = [
        hd.seg.SegmentDescription(
            segment_number=1,
            segment_label="IAN canal",
            segmented_property_category=codes.SCT.Tissue,
            segmented_property_type=codes.SCT.Nerve,
            algorithm_type=hd.seg.SegmentAlgorithmTypeValues.MANUAL,
        )
    ]
    kwargs: dict[str, object] = {}
    if own_grid:
        n_k, rows, cols = 9, 6, 7
        mask = np.zeros((n_k, rows, cols), dtype=bool)
        mask[2, 1:4, 2] = True
        mask[6, 3, 1:6] = True  # frames 3-5 and others empty: omitted by highdicom
        e_i, e_j, normal = ROT[:, 0], ROT[:, 1], ROT[:, 2]
        kwargs = {
            "pixel_measures": hd.PixelMeasuresSequence(
                pixel_spacing=(float(SPACING[1]), float(SPACING[0])),
                slice_thickness=float(SPACING[2]),
                spacing_between_slices=float(SPACING[2]),
            ),
            "plane_orientation": hd.PlaneOrientationSequence(
                coordinate_system="PATIENT",
                image_orientation=(*e_i.tolist(), *e_j.tolist()),
            ),
            "plane_positions": [
                hd.PlanePositionSequence(
                    coordinate_system="PATIENT",
                    image_position=(ORIGIN_LPS + k * SPACING[2] * normal).tolist(),
                )
                for k in range(n_k)
            ],
        }
        affine = AFFINE_LPS
    else:
        mask = np.zeros(volume.hu.shape, dtype=bool)
        mask[40:43, 50, 10:70] = True
        affine = volume.affine_lps
    seg = hd.seg.Segmentation(
        source_images=sources,
        pixel_array=mask.astype(np.uint8),
        segmentation_type=hd.seg.SegmentationTypeValues.BINARY,
        segment_descriptions=desc,
        series_instance_uid=hd.UID(),
        series_number=100,
        sop_instance_uid=hd.UID(),
        instance_number=1,
        manufacturer="ctdrill tests",
        manufacturer_model_name="highdicom",
        software_versions="0",
        device_serial_number="1",
        **kwargs,
    )
    path = tmp_path / "seg.dcm"
    seg.save_as(path)
    return path, mask, affine


@pytest.mark.parametrize("own_grid", [False, True])
def test_dicom_seg_written_by_highdicom(tmp_path: Path, own_grid: bool) -> None:
    _path, mask, affine = _dicom_seg(tmp_path, own_grid=own_grid)
    plan = load_plan(
        _plan_with(tmp_path, {"kind": "mask", "path": "seg.dcm", "segment": "IAN canal"})
    )
    lm = plan.landmarks[0]
    assert isinstance(lm, MaskLandmark)
    # The SEG omits empty frames: the grid spans the first to the last frame with voxels.
    ks = np.flatnonzero(mask.any(axis=(1, 2)))
    expected = mask[ks[0] : ks[-1] + 1]
    shifted = affine.copy()
    shifted[:3, 3] = affine[:3, 3] + ks[0] * affine[:3, 2]
    assert isinstance(lm.affine_lps, np.ndarray)
    np.testing.assert_allclose(lm.affine_lps, shifted, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(lm.mask, expected)


def test_dicom_that_is_not_a_seg_is_refused(tmp_path: Path) -> None:
    ct = sorted((ASSETS / "demo" / "ct").glob("*.dcm"))[0]
    lm = {"kind": "mask", "path": str(ct)}
    with pytest.raises(LandmarkInputError, match="not a DICOM Segmentation"):
        load_plan(_plan_with(tmp_path, lm))


# --------------------------------------------------------------------------- hostile masks


def test_npz_named_npy_is_refused(tmp_path: Path) -> None:
    np.savez(tmp_path / "m.npz", a=np.ones((2, 2, 2), dtype=np.uint8))
    os.replace(tmp_path / "m.npz", tmp_path / "m.npy")
    with pytest.raises(LandmarkInputError, match=r"not a readable \.npy labelmap"):
        load_plan(_plan_with(tmp_path, {"kind": "mask", "path": "m.npy"}))


def test_tiny_npy_declaring_477_gib_is_refused_before_allocating(tmp_path: Path) -> None:
    shape = (8000, 8000, 8000)  # uint8: 477 GiB
    header = {"descr": "|u1", "fortran_order": False, "shape": shape}
    path = tmp_path / "bomb.npy"
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(fh, header)
        fh.write(b"\0" * 65)
    assert path.stat().st_size == 193
    with pytest.raises(LandmarkInputError, match=rf"more than the {MAX_MASK_BYTES} accepted"):
        read_npy(path)
    # Within the bound but larger than the file: refused before reading too.
    header["shape"] = (100, 100, 100)
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(fh, header)
        fh.write(b"\0" * 65)
    with pytest.raises(LandmarkInputError, match="the header declares 1000000 bytes of data"):
        read_npy(path)


def test_nrrd_header_declaring_a_huge_volume_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "bomb.nrrd"
    path.write_bytes(
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8000 8000 8000\nencoding: gzip\n"
        b"space: left-posterior-superior\n\n" + b"\0" * 100
    )
    with pytest.raises(LandmarkInputError, match="more than the"):
        load_plan(_plan_with(tmp_path, {"kind": "mask", "path": "bomb.nrrd"}))
    path.write_bytes(
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
        b"space: left-posterior-superior\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n"
        b"space origin: (0,0,0)\ndata file: /dev/zero\n\n"
    )
    with pytest.raises(
        LandmarkInputError, match=r"/dev/zero: the NRRD data file named by .* is a device"
    ):
        load_plan(_plan_with(tmp_path, {"kind": "mask", "path": "bomb.nrrd"}))


@pytest.mark.parametrize("name", ["fifo.npy", "fifo.seg.nrrd", "fifo.nii.gz", "fifo.dcm"])
def test_fifo_and_device_mask_paths_are_refused(tmp_path: Path, name: str) -> None:
    os.mkfifo(tmp_path / name)
    with pytest.raises(LandmarkInputError, match="a named pipe"):
        load_plan(_plan_with(tmp_path, {"kind": "mask", "path": name}))
    with pytest.raises(LandmarkInputError, match="a device"):
        load_plan(_plan_with(tmp_path, {"kind": "mask", "path": "/dev/zero"}))


def test_plan_inputs_that_are_fifos_are_refused(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "plan.mrk.json")
    with pytest.raises(PlanInputError, match="a named pipe"):
        load_plan(tmp_path / "plan.mrk.json")
