"""Canal geometry is exact or refused (issue 29): a canal segmentation that lies is never moved.

The demo phantom's canal (ground_truth.json: a 1.2 mm tube) is voxelised on the demo CT's grid
and stored as a DICOM SEG (written by highdicom), a NIfTI (nibabel) and a NRRD (pynrrd). The
good files put the stop on the margin, as the canal itself does (10.8 mm, inside one voxel);
every damaged variant, one per class of lie (orientation not unit or not perpendicular,
positions not finite, missing or empty fields, a spacing that asks for gigabytes, NIfTI without
codes or with two geometries), is refused naming the file and the field, through the Python
API and through ``ctdrill export``: the drill can no longer pass through a misplaced canal to
the planned 12.0 mm.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pydicom
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.landmarks import LandmarkInputError
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.safety import safe_depth
from tests.conftest import ASSETS
from tests.imaging.volume_writers import write_nifti, write_nrrd

DEMO = ASSETS / "demo"
#: The canal's own margin stop on the demo (DESIGN: planned 12.0, margin stop 10.8 mm).
CANAL_STOP_MM = 10.8
VOXEL_MM = 0.4


@pytest.fixture(scope="module")
def canal(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The demo canal voxelised on the CT grid, and a SEG of it written by highdicom."""
    import highdicom as hd
    from pydicom.sr.codedict import codes

    truth = json.loads((DEMO / "ground_truth.json").read_text())
    line = np.asarray(truth["canal"]["centerline_lps"], dtype=np.float64)
    radius = float(truth["canal"]["radius_mm"])
    volume = load_series(DEMO / "ct")
    k, j, i = np.indices(volume.hu.shape)
    centres = volume.index_to_lps(np.stack([i, j, k], axis=-1).reshape(-1, 3))
    near = np.all((centres >= line.min(0) - radius - 1) & (centres <= line.max(0) + radius + 1), 1)
    pts = centres[near]
    a, b = line[:-1], line[1:]
    ab = b - a
    best = np.full(len(pts), np.inf)
    for s in range(len(a)):  # distance to each segment of the centreline
        t = np.clip(((pts - a[s]) @ ab[s]) / (ab[s] @ ab[s]), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(pts - (a[s] + t[:, None] * ab[s]), axis=1))
    inside = np.zeros(len(centres), dtype=bool)
    inside[np.flatnonzero(near)[best <= radius]] = True
    mask = inside.reshape(volume.hu.shape)
    folder = tmp_path_factory.mktemp("canal")
    slices = np.flatnonzero(mask.any(axis=(1, 2)))  # the SEG's source images: these slices
    files = sorted((DEMO / "ct").glob("*.dcm"))
    sources = [pydicom.dcmread(files[n]) for n in slices]
    np.testing.assert_allclose(
        [float(s.ImagePositionPatient[2]) for s in sources],
        volume.slice_origins_lps[slices, 2],
        atol=1e-9,
    )
    seg = hd.seg.Segmentation(
        source_images=sources,
        pixel_array=mask[slices].astype(np.uint8),
        segmentation_type=hd.seg.SegmentationTypeValues.BINARY,
        segment_descriptions=[
            hd.seg.SegmentDescription(
                segment_number=1,
                segment_label="IAN canal",
                segmented_property_category=codes.SCT.Tissue,
                segmented_property_type=codes.SCT.Nerve,
                algorithm_type=hd.seg.SegmentAlgorithmTypeValues.MANUAL,
            )
        ],
        series_instance_uid=hd.UID(),
        series_number=100,
        sop_instance_uid=hd.UID(),
        instance_number=1,
        manufacturer="ctdrill tests",
        manufacturer_model_name="highdicom",
        software_versions="0",
        device_serial_number="1",
    )
    seg.save_as(folder / "canal.dcm")
    return {"mask": mask, "affine": np.asarray(volume.affine_lps), "folder": folder}


def _plan(folder: Path, mask_name: str) -> Path:
    doc = json.loads((DEMO / "plan.json").read_text())
    doc["landmarks"] = [{"name": "canal", "kind": "mask", "path": mask_name}]
    doc.pop("series_sha256", None)
    path = folder / f"plan-{mask_name}.json"
    path.write_text(json.dumps(doc))
    return path


def _stop_mm(plan_path: Path) -> float:
    plan = load_plan(plan_path)
    return float(min(safe_depth(plan).depth_mm, plan.planned_depth_mm))


def test_good_files_stop_on_the_margin(canal: dict[str, Any], tmp_path: Path) -> None:
    mask, affine = canal["mask"], canal["affine"]
    write_nifti(tmp_path / "canal.nii.gz", mask.astype(np.uint8), affine)
    write_nrrd(tmp_path / "canal.nrrd", mask.astype(np.uint8), affine)
    (tmp_path / "canal.dcm").write_bytes((canal["folder"] / "canal.dcm").read_bytes())
    stops = {
        name: _stop_mm(_plan(tmp_path, name))
        for name in ("canal.dcm", "canal.nii.gz", "canal.nrrd")
    }
    for name, stop in stops.items():
        assert abs(stop - CANAL_STOP_MM) <= VOXEL_MM, (name, stop)
    assert max(stops.values()) - min(stops.values()) < 1e-3, stops


# --------------------------------------------------------------------------- DICOM SEG lies


def _shared(ds: Any, seq: str) -> Any:
    return ds.SharedFunctionalGroupsSequence[0][seq][0]


def _frame(ds: Any, n: int, seq: str) -> Any:
    return ds.PerFrameFunctionalGroupsSequence[n][seq][0]


def _iop_scaled_x10(ds: Any) -> None:
    item = _shared(ds, "PlaneOrientationSequence")
    item.ImageOrientationPatient = [10 * float(v) for v in item.ImageOrientationPatient]


def _iop_skewed(ds: Any) -> None:
    item = _shared(ds, "PlaneOrientationSequence")
    c, s = np.cos(0.05), np.sin(0.05)
    item.ImageOrientationPatient = [1.0, 0.0, 0.0, float(s), float(c), 0.0]


def _iop_nan(ds: Any) -> None:
    _shared(ds, "PlaneOrientationSequence").ImageOrientationPatient = [1, 0, 0, 0, "NaN", 0]


def _ipp_nan(ds: Any) -> None:
    _frame(ds, 1, "PlanePositionSequence").ImagePositionPatient = ["NaN", "NaN", "NaN"]


def _ipp_inf(ds: Any) -> None:
    _frame(ds, 0, "PlanePositionSequence").ImagePositionPatient = [0.0, "inf", 0.0]


def _no_segment_sequence(ds: Any) -> None:
    del ds.SegmentSequence


def _empty_segment_sequence(ds: Any) -> None:
    ds.SegmentSequence = []


def _identification(ds: Any, n: int) -> Any:
    """Frame ``n``'s SegmentIdentificationSequence item, made per-frame when it was shared."""
    frame = ds.PerFrameFunctionalGroupsSequence[n]
    if "SegmentIdentificationSequence" not in frame:
        from copy import deepcopy

        shared = ds.SharedFunctionalGroupsSequence[0]
        for item in ds.PerFrameFunctionalGroupsSequence:
            item.SegmentIdentificationSequence = deepcopy(shared.SegmentIdentificationSequence)
        del shared.SegmentIdentificationSequence
    return frame.SegmentIdentificationSequence[0]


def _no_referenced_number(ds: Any) -> None:
    del _identification(ds, 2).ReferencedSegmentNumber


def _referenced_unknown(ds: Any) -> None:
    _identification(ds, 2).ReferencedSegmentNumber = 7


def _one_value_spacing(ds: Any) -> None:
    _shared(ds, "PixelMeasuresSequence").PixelSpacing = [0.4]


def _zero_spacing(ds: Any) -> None:
    _shared(ds, "PixelMeasuresSequence").PixelSpacing = [0.4, 0.0]


def _empty_segment_number(ds: Any) -> None:
    ds.SegmentSequence[0].SegmentNumber = None


def _no_rows(ds: Any) -> None:
    del ds.Rows


def _gigabyte_spacing(ds: Any) -> None:
    """The last frame 1000 mm on, at SpacingBetweenSlices 0.00125 mm: 800,000+ slices."""
    _shared(ds, "PixelMeasuresSequence").SpacingBetweenSlices = 0.00125
    last = _frame(ds, len(ds.PerFrameFunctionalGroupsSequence) - 1, "PlanePositionSequence")
    x, y, z = (float(v) for v in last.ImagePositionPatient)
    last.ImagePositionPatient = [x, y, z + 1000.0]


def _frames_without_items(ds: Any) -> None:
    ds.NumberOfFrames = int(ds.NumberOfFrames) + 1


def _frames_terabytes(ds: Any) -> None:
    ds.NumberOfFrames = 10**9


def _per_frame_measures(ds: Any) -> None:
    """Every frame its own PixelMeasuresSequence (as a scanner's SEG may give them)."""
    from copy import deepcopy

    shared = ds.SharedFunctionalGroupsSequence[0]
    for item in ds.PerFrameFunctionalGroupsSequence:
        item.PixelMeasuresSequence = deepcopy(shared.PixelMeasuresSequence)
    del shared.PixelMeasuresSequence


def _frame_spacing_differs(ds: Any) -> None:
    _per_frame_measures(ds)
    _frame(ds, 2, "PixelMeasuresSequence").PixelSpacing = [0.41, 0.4]


def _frame_slice_spacing_differs(ds: Any) -> None:
    _per_frame_measures(ds)
    for n in range(len(ds.PerFrameFunctionalGroupsSequence)):
        _frame(ds, n, "PixelMeasuresSequence").SpacingBetweenSlices = 0.4
    _frame(ds, 4, "PixelMeasuresSequence").SpacingBetweenSlices = 0.5


def _frame_orientation_differs(ds: Any) -> None:
    from copy import deepcopy

    shared = ds.SharedFunctionalGroupsSequence[0]
    for item in ds.PerFrameFunctionalGroupsSequence:
        item.PlaneOrientationSequence = deepcopy(shared.PlaneOrientationSequence)
    del shared.PlaneOrientationSequence
    c, s = np.cos(0.01), np.sin(0.01)
    _frame(ds, 1, "PlaneOrientationSequence").ImageOrientationPatient = [
        float(c),
        float(s),
        0.0,
        float(-s),
        float(c),
        0.0,
    ]


SEG_LIES: dict[str, tuple[Callable[[Any], None], str]] = {
    "frame_spacing_differs": (
        _frame_spacing_differs,
        r"frame 3 \(PixelMeasuresSequence\) PixelSpacing \[0\.41, 0\.4\] differs from frame 1's",
    ),
    "frame_slice_spacing_differs": (
        _frame_slice_spacing_differs,
        r"frame 5 \(PixelMeasuresSequence\) SpacingBetweenSlices 0\.5 differs from frame 1's 0\.4",
    ),
    "frame_orientation_differs": (
        _frame_orientation_differs,
        r"frame 2 \(PlaneOrientationSequence\) ImageOrientationPatient differs from frame 1's",
    ),
    "iop_scaled_x10": (_iop_scaled_x10, r"ImageOrientationPatient: direction 1 has length 10"),
    "iop_skewed": (_iop_skewed, r"ImageOrientationPatient: directions 1 and 2 are not perp"),
    "iop_nan": (_iop_nan, r"ImageOrientationPatient \[.*nan.*\] is not finite"),
    "ipp_nan": (_ipp_nan, r"frame 2 \(PlanePositionSequence\): ImagePositionPatient \[nan"),
    "ipp_inf": (_ipp_inf, r"frame 1 \(PlanePositionSequence\): ImagePositionPatient .*inf"),
    "no_segment_sequence": (_no_segment_sequence, r"SegmentSequence is missing or empty"),
    "empty_segment_sequence": (_empty_segment_sequence, r"SegmentSequence is missing or empty"),
    "no_referenced_number": (
        _no_referenced_number,
        r"frame 3 .*ReferencedSegmentNumber is missing",
    ),
    "referenced_unknown": (_referenced_unknown, r"ReferencedSegmentNumber 7 names no segment"),
    "one_value_spacing": (_one_value_spacing, r"PixelSpacing holds 1 value\(s\), a SEG gives 2"),
    "zero_spacing": (_zero_spacing, r"PixelSpacing must be positive"),
    "empty_segment_number": (_empty_segment_number, r"segment item 1: SegmentNumber is missing"),
    "no_rows": (_no_rows, r"Rows is missing"),
    "frames_without_items": (_frames_without_items, r"PerFrameFunctionalGroupsSequence items"),
    "frames_terabytes": (_frames_terabytes, r"NumberOfFrames x Rows x Columns declares .* more"),
    "gigabyte_spacing": (
        _gigabyte_spacing,
        r"SpacingBetweenSlices 0\.00125 mm \(\d{6} slices\).*more than",
    ),
}


def _lying_seg(canal: dict[str, Any], folder: Path, name: str) -> Path:
    ds = pydicom.dcmread(canal["folder"] / "canal.dcm")
    SEG_LIES[name][0](ds)
    path = folder / f"{name}.dcm"
    ds.save_as(path)
    return path


@pytest.mark.filterwarnings("ignore:Invalid value for VR DS")
@pytest.mark.parametrize("name", sorted(SEG_LIES))
def test_lying_seg_is_refused_naming_the_field(
    canal: dict[str, Any], tmp_path: Path, name: str
) -> None:
    path = _lying_seg(canal, tmp_path, name)
    with pytest.raises(LandmarkInputError) as err:
        load_plan(_plan(tmp_path, path.name))
    message = str(err.value)
    assert message.startswith(str(path)), message
    assert re.search(SEG_LIES[name][1], message), message


# --------------------------------------------------------------------------- NIfTI lies


def _nifti_no_codes(folder: Path, mask: np.ndarray, affine: np.ndarray) -> Path:
    return write_nifti(folder / "nocodes.nii.gz", mask, affine, sform_code=0, qform_code=0)


def _nifti_two_geometries(folder: Path, mask: np.ndarray, affine: np.ndarray) -> Path:
    moved = affine.copy()
    moved[:3, 3] += [0.0, 6.0, 0.0]
    return write_nifti(folder / "two.nii.gz", mask, affine, qform_lps=moved)


NIFTI_LIES = {
    "no_codes": (_nifti_no_codes, r"qform_code and sform_code are both 0"),
    "qform_sform": (
        _nifti_two_geometries,
        r"qform \(qform_code 1\) and the sform \(sform_code 1\) place voxels up to 6 mm apart",
    ),
}


@pytest.mark.parametrize("name", sorted(NIFTI_LIES))
def test_lying_nifti_is_refused(canal: dict[str, Any], tmp_path: Path, name: str) -> None:
    build, pattern = NIFTI_LIES[name]
    path = build(tmp_path, canal["mask"].astype(np.uint8), canal["affine"])
    with pytest.raises(LandmarkInputError, match=pattern):
        load_plan(_plan(tmp_path, path.name))


@pytest.mark.filterwarnings("ignore:Invalid value for VR DS")
@pytest.mark.parametrize(
    "case",
    [
        "seg:iop_scaled_x10",
        "seg:ipp_nan",
        "seg:frame_spacing_differs",
        "nifti:no_codes",
        "nifti:qform_sform",
    ],
)
def test_export_refuses_with_one_error_line(
    canal: dict[str, Any], tmp_path: Path, case: str
) -> None:
    kind, name = case.split(":")
    if kind == "seg":
        path = _lying_seg(canal, tmp_path, name)
    else:
        path = NIFTI_LIES[name][0](tmp_path, canal["mask"].astype(np.uint8), canal["affine"])
    out, err = io.StringIO(), io.StringIO()
    argv = [
        "export",
        "--dicom",
        str(DEMO / "ct"),
        "--plan",
        str(_plan(tmp_path, path.name)),
        "--out",
        str(tmp_path / "out"),
    ]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    assert code == 2
    lines = err.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}"), err.getvalue()
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- per frame, frames


def test_per_frame_measures_that_agree_are_honoured(canal: dict[str, Any], tmp_path: Path) -> None:
    ds = pydicom.dcmread(canal["folder"] / "canal.dcm")
    _per_frame_measures(ds)
    ds.save_as(tmp_path / "per_frame.dcm")
    assert abs(_stop_mm(_plan(tmp_path, "per_frame.dcm")) - CANAL_STOP_MM) <= VOXEL_MM


def test_a_seg_of_another_frame_of_reference_is_refused_naming_both(
    canal: dict[str, Any], tmp_path: Path
) -> None:
    from ctdrill import api

    volume = api.load_ct(DEMO / "ct")
    ct_frame = volume.info.frame_of_reference_uid
    ds = pydicom.dcmread(canal["folder"] / "canal.dcm")
    assert ct_frame and str(ds.FrameOfReferenceUID) == ct_frame  # highdicom copies the CT's
    result = api.plan_path(volume, api.load_plan(_plan(tmp_path, _copy(canal, tmp_path))))
    assert result.stop_reason == "margin"
    ds.FrameOfReferenceUID = "1.2.826.0.1.3680043.8.498.4242"
    ds.save_as(tmp_path / "other.dcm")
    plan = _plan(tmp_path, "other.dcm")
    with pytest.raises(
        Exception, match=r"Frame of Reference 1\.2\.826\.0\.1\.3680043\.8\.498\.4242"
    ):
        api.plan_path(volume, api.load_plan(plan))
    out, err = io.StringIO(), io.StringIO()
    argv = [
        "export",
        "--dicom",
        str(DEMO / "ct"),
        "--plan",
        str(plan),
        "--out",
        str(tmp_path / "o"),
    ]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    lines = err.getvalue().splitlines()
    assert code == 2 and len(lines) == 1, err.getvalue()
    assert "1.2.826.0.1.3680043.8.498.4242" in lines[0] and ct_frame in lines[0]
    assert not (tmp_path / "o").exists()


def _copy(canal: dict[str, Any], folder: Path) -> str:
    (folder / "canal.dcm").write_bytes((canal["folder"] / "canal.dcm").read_bytes())
    return "canal.dcm"
