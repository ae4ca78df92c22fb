"""Hard-input DICOM corpus: every case is written with pydicom and knows its expected outcome.

``build_corpus(out_dir)`` writes one directory per synthetic case under ``out_dir`` and returns
the synthetic cases followed by the real series of ``../shared/data``. A case expects either a
load (with exactly the listed warning codes, plus any listed as optional) or a refusal
(``ImagingInputError``; the CLI exits 2 with one ``error:`` line). Where two outcomes are both
defensible (a corrupt slice may be skipped *and reported*, or the series refused), the case lists
both alternatives; a silent load or a traceback is never one of them.

Run ``python -m tests.robustness.make_corpus OUT`` to write the corpus for manual inspection.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from tests.robustness.corpus_base import (
    COLS,
    PHI,
    ROOT,
    ROWS,
    SHARED_DATA,
    SLICE_SPACING_MM,
    Case,
    Expect,
    base_affine,
    base_hu,
    load,
    uid,
)
from tests.robustness.corpus_faults import (
    OBLIQUE_IOP,
    TILT_IOP,
    Builder,
    _bad_value,
    _bomb_element_length,
    _bomb_frames,
    _bomb_header_element_length,
    _bomb_one_element_length,
    _bomb_rows_cols,
    _clean,
    _colour_beside,
    _colour_series,
    _deep_nesting,
    _device_links,
    _dicomdir,
    _duplicate_conflicting,
    _duplicate_identical,
    _empty_dir,
    _fifo,
    _gantry_tilt,
    _gap,
    _implicit_vr,
    _j2k_lossy,
    _junk_beside,
    _junk_only,
    _localizer,
    _meta_misaligned,
    _missing,
    _missing_ipp_one,
    _mixed_dims,
    _mixed_orientation,
    _no_such_dir,
    _nonuniform,
    _not_hu,
    _oblique,
    _padding,
    _rle_lossless,
    _rows_wrong_vr,
    _short_pixeldata,
    _short_pixeldata_all,
    _single_slice,
    _slope_wrong_vr,
    _symlink_loop,
    _transfer_syntax,
    _truncated_header,
    _truncated_pixels,
    _two_series,
    _undefined_root_transfer_syntax,
    _unknown_vr,
)
from tests.robustness.corpus_hostile import (
    _nested_undefined,
    _rle_fragment_bomb,
    _rle_offset_table_bomb,
    _rle_segment_bomb,
)
from tests.robustness.corpus_real import real_cases

__all__ = [
    "PHI",
    "ROOT",
    "SHARED_DATA",
    "SYNTHETIC",
    "Case",
    "Expect",
    "build_corpus",
    "case_names",
    "uid",
]

#: name -> (builder, fault group, isolate: run only in a capped child process)
SYNTHETIC: dict[str, tuple[Builder, str, bool]] = {
    "clean": (_clean, "none (reference)", False),
    "implicit_vr": (_implicit_vr, "none (implicit VR)", False),
    "oblique": (_oblique, "none (oblique, not sheared)", False),
    "gantry_tilt": (_gantry_tilt, "geometry", False),
    "truncated_pixels": (_truncated_pixels, "truncated file", False),
    "truncated_header": (_truncated_header, "truncated file", False),
    "short_pixeldata": (_short_pixeldata, "short PixelData", False),
    "short_pixeldata_all": (_short_pixeldata_all, "short PixelData", False),
    "missing_ipp": (_missing("ImagePositionPatient"), "missing geometry", False),
    "missing_iop": (_missing("ImageOrientationPatient"), "missing geometry", False),
    "missing_pixel_spacing": (_missing("PixelSpacing"), "missing geometry", False),
    "missing_ipp_one_slice": (_missing_ipp_one, "missing geometry", False),
    "missing_pixeldata": (_missing("PixelData"), "missing pixels", False),
    "zero_pixel_spacing": (_bad_value("PixelSpacing", [0.0, 0.0]), "bad value", False),
    "negative_pixel_spacing": (_bad_value("PixelSpacing", [-0.6, 0.5]), "bad value", False),
    "nan_pixel_spacing": (
        _bad_value("PixelSpacing", "nan\\nan", vr="DS"),
        "bad value",
        False,
    ),
    "inf_position": (
        _bad_value("ImagePositionPatient", "inf\\0\\0", vr="DS"),
        "bad value",
        False,
    ),
    "zero_orientation": (_bad_value("ImageOrientationPatient", [0.0] * 6), "bad value", False),
    "nonorthogonal_orientation": (
        _bad_value("ImageOrientationPatient", [1.0, 0.0, 0.0, 1.0, 0.0, 0.0]),
        "bad value",
        False,
    ),
    "zero_rescale_slope": (_bad_value("RescaleSlope", 0.0), "bad value", False),
    "text_position": (
        _bad_value("ImagePositionPatient", "left\\up\\down", vr="LO"),
        "wrong VR",
        False,
    ),
    "rows_as_ds": (_rows_wrong_vr, "wrong VR", False),
    "slope_as_fd": (_slope_wrong_vr, "wrong VR", False),
    "duplicate_identical": (_duplicate_identical, "duplicates", False),
    "duplicate_conflicting": (_duplicate_conflicting, "duplicates", False),
    "slice_gap": (_gap, "gaps and spacing", False),
    "nonuniform_spacing": (_nonuniform, "gaps and spacing", False),
    "two_series": (_two_series, "two series", False),
    "localizer": (_localizer, "localizer", False),
    "junk_beside_series": (_junk_beside, "junk and non-image files", False),
    "junk_only": (_junk_only, "junk and non-image files", False),
    "empty_dir": (_empty_dir, "junk and non-image files", False),
    "no_such_dir": (_no_such_dir, "junk and non-image files", False),
    "dicomdir_with_images": (
        lambda f: _dicomdir(f, with_images=True),
        "DICOMDIR",
        False,
    ),
    "dicomdir_only": (lambda f: _dicomdir(f, with_images=False), "DICOMDIR", False),
    "colour_series_claiming_hu": (_colour_series, "colour claiming HU", False),
    "colour_capture_beside": (_colour_beside, "colour claiming HU", False),
    "rescale_type_us": (_not_hu, "not HU", False),
    "padding": (_padding, "padding", False),
    "mixed_dims": (_mixed_dims, "inconsistent slices", False),
    "mixed_orientation": (_mixed_orientation, "inconsistent slices", False),
    "rle_lossless": (_rle_lossless, "none (RLE lossless)", False),
    "j2k_lossy": (_j2k_lossy, "lossy compression", False),
    "unknown_vr": (_unknown_vr, "corrupt header", False),
    "meta_misaligned": (_meta_misaligned, "corrupt header", False),
    # Deflated Explicit VR Little Endian (PS3.5 A.5): defined, pydicom inflates it on write/read.
    "deflated_transfer_syntax": (
        _transfer_syntax("1.2.840.10008.1.2.1.99", load()),
        "none (deflated)",
        False,
    ),
    "unknown_transfer_syntax": (
        _undefined_root_transfer_syntax,
        "transfer syntax",
        False,
    ),
    "private_transfer_syntax": (
        _transfer_syntax("1.2.840.12008.1.2.1"),
        "transfer syntax",
        False,
    ),
    "deep_nesting": (_deep_nesting, "recursion bomb", False),
    "nested_undefined_sequences": (_nested_undefined, "recursion bomb", False),
    "symlink_loop": (_symlink_loop, "file system", False),
    "fifo_in_folder": (_fifo, "file system", True),
    "device_symlinks": (_device_links, "file system", True),
    "single_slice": (_single_slice, "not a volume", False),
    "bomb_rows_cols_65535": (_bomb_rows_cols, "memory bomb", True),
    "bomb_number_of_frames": (_bomb_frames, "memory bomb", True),
    "bomb_pixel_length_all": (_bomb_element_length, "memory bomb", True),
    "bomb_pixel_length_one": (_bomb_one_element_length, "memory bomb", True),
    "bomb_header_element_length": (_bomb_header_element_length, "memory bomb", True),
    "bomb_rle_offset_table": (_rle_offset_table_bomb, "memory bomb", True),
    "bomb_rle_fragment_length": (_rle_fragment_bomb, "memory bomb", True),
    "bomb_rle_segments": (_rle_segment_bomb, "memory bomb", True),
}

#: Cases whose exact HU and affine are known.
_EXACT: dict[str, tuple[Callable[[], np.ndarray], Callable[[], np.ndarray]]] = {
    "clean": (base_hu, base_affine),
    "implicit_vr": (base_hu, base_affine),
    "rle_lossless": (base_hu, base_affine),
    "oblique": (
        base_hu,
        lambda: base_affine(OBLIQUE_IOP[:3], OBLIQUE_IOP[3:], (0.0, 0.0, SLICE_SPACING_MM)),
    ),
    "gantry_tilt": (base_hu, lambda: base_affine(TILT_IOP[:3], TILT_IOP[3:], (0.0, 0.0, 1.0))),
}


def case_names(*, include_real: bool = True) -> list[str]:
    """Names of the cases :func:`build_corpus` returns, in order, without writing anything."""
    names = [*SYNTHETIC, "two_series_select_b"]
    return names + ([c.name for c in real_cases()] if include_real else [])


def build_corpus(out_dir: Path, *, include_real: bool = True) -> list[Case]:
    """Write every synthetic case under ``out_dir`` and return all cases (synthetic, then real).

    Parameters
    ----------
    out_dir : directory to write into (created; must not hold an older corpus).
    include_real : append the real series of ``../shared/data`` (read in place, not copied).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cases: list[Case] = []
    for name, (builder, fault, bomb) in SYNTHETIC.items():
        folder = out_dir / name
        with warnings.catch_warnings():  # pydicom warns about the invalid values we write
            warnings.simplefilter("ignore")
            expected = builder(folder)
        case = Case(name, folder, expected, fault, isolate=bomb)
        if name in _EXACT:
            hu, affine = _EXACT[name]
            case = replace(case, hu=hu(), affine_lps=affine())
        cases.append(case)
    select_b = replace(
        next(c for c in cases if c.name == "two_series"),
        name="two_series_select_b",
        expected=(load(dims=(COLS, ROWS, 5), optional=["multiple_series"]),),
        series_uid=uid("series-b"),
    )
    cases.append(select_b)
    if include_real:
        cases.extend(real_cases())
    return cases


if __name__ == "__main__":
    target = Path(sys.argv[1] if len(sys.argv) > 1 else "robustness-corpus")
    for built in build_corpus(target):
        print(f"{built.name:32s} {' | '.join(e.describe() for e in built.expected)}")
