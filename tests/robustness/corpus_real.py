"""The real series of ``../shared/data`` and what a correct loader does with each (its README)."""

from __future__ import annotations

from pathlib import Path

from tests.robustness.corpus_base import REFUSE, SHARED_DATA, Case, Expect, load


def real_cases(data: Path = SHARED_DATA) -> list[Case]:
    """The real series of ``../shared/data`` with the outcomes its README states (and
    ``coarse_voxels``: every one of them has slices or pixels coarser than implant planning
    needs, ``imaging/resolution.py``)."""
    d2n = data / "dicom2nifti_ct_geometry_edgecases"
    single = data / "single_slice_ct"
    # Every real folder holds SOURCE.txt / JSON beside the DICOM files.
    skipped = ["files_skipped"]
    rows: list[tuple[str, Path, tuple[Expect, ...], str]] = [
        (
            "real_ge_head_tilt_varspacing",
            data / "dcmqa_ct_GE_head_gantrytilt_varspacing",
            (
                load(
                    "gantry_tilt",
                    "nonuniform_spacing",
                    "padding",
                    "coarse_voxels",
                    optional=skipped,
                ),
            ),
            "real: geometry",
        ),
        (
            "real_philips_mixedfolder",
            data / "dcmqa_ct_Philips_phantom_gantrytilt_mixedfolder",
            (
                load(
                    "multiple_series",
                    "localizer_dropped",
                    "files_skipped",
                    "gantry_tilt",
                    "coarse_voxels",
                    optional=["padding"],
                ),
            ),
            "real: mixed folder",
        ),
        (
            "real_philips_notilt",
            data / "dcmqa_ct_Philips_phantom_notilt_5mm",
            (load("coarse_voxels", optional=skipped),),
            "real: clean but for its 5 mm slices",
        ),
        (
            "real_ge_abdomen_3slice",
            data / "dcmqi_ct_3slice_GE_abdomen",
            (load("padding", "coarse_voxels", optional=skipped),),
            "real: implicit VR, feet first",
        ),
        (
            "real_siemens_tilt_iop_only",
            d2n / "gantrytilting_siemens_14deg",
            (load("gantry_tilt", "coarse_voxels"),),
            "real: geometry",
        ),
        (
            "real_ge_missing_slice",
            d2n / "sliceincrement_ge_missing_slice",
            (load("slice_gap", "coarse_voxels", optional=["nonuniform_spacing"]),),
            "real: geometry",
        ),
        (
            "real_siemens_tilt_missing_slice",
            d2n / "sliceincrement_siemens_tilt_missing_slice",
            (load("gantry_tilt", "slice_gap", "coarse_voxels", optional=["nonuniform_spacing"]),),
            "real: geometry",
        ),
        (
            "real_four_files_one_position",
            d2n / "notavolume_siemens_same_position",
            (REFUSE,),
            "real: not a volume",
        ),
        (
            "real_enhanced_ct_multiframe",
            single / "pydicom_data_repo",
            (load("not_hu", "coarse_voxels", optional=skipped),),
            "real: multi-frame",
        ),
        (
            "real_colour_ct_pictures",
            single / "deid_data_pypi",
            (REFUSE,),
            "real: colour claiming HU",
        ),
        (
            "real_rt_planning_single_slice",
            single / "dicompyler_core",
            (REFUSE, load("single_slice", "coarse_voxels", optional=skipped)),
            "real: not a volume",
        ),
    ]
    return [Case(name, path, expected, fault, real=True) for name, path, expected, fault in rows]
