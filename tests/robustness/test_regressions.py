"""Bugs the robustness tests found, now fixed: each minimal input keeps its correct outcome.

Also fixed and covered by the corpus itself (``test_corpus.py``, ``test_memory_bombs.py``):
``zero_rescale_slope`` (loaded silently), ``bomb_number_of_frames`` (NumberOfFrames 2147483647
loaded as one slice), ``bomb_pixel_length_all/_one`` (PixelData declaring 4 GiB in a 1 kB file
loaded), ``bomb_header_element_length`` (MemoryError under RLIMIT_AS), ``private_transfer_syntax``
(ValueError from the decoder lookup), ``unknown_vr`` (NotImplementedError from pydicom),
``fifo_in_folder`` (the loader blocked forever opening a named pipe).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ctdrill.model.errors import ModelInputError
from tests.robustness.make_corpus import ROOT, Case


def _write(tmp_path: Path, name: str, doc: object) -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def test_calibration_with_integer_beyond_float_range_is_refused(tmp_path: Path) -> None:
    """calibration-int-overflow: ``"gate_hu": 10**400`` -> OverflowError in float()."""
    from ctdrill.model import ModelInputError, load_calibration
    from tests.robustness.fuzz import seed_calibration

    doc = {**seed_calibration(), "gate_hu": 10**400}
    with pytest.raises(ModelInputError):
        load_calibration(_write(tmp_path, "cal.json", doc))


@pytest.mark.parametrize(
    ("field", "value"), [("b0", 400.0), ("n", 500.0), ("ke", 1e308)], ids=["b0", "n", "ke"]
)
def test_calibration_whose_law_overflows_is_refused(
    tmp_path: Path, field: str, value: float
) -> None:
    """calibration-law-unbounded: accepted, then A0 is inf (or OverflowError) at every HU.

    DESIGN.md 1.6: no NaN or inf may leave the model for any int16 HU and any finite feed, so a
    set whose A0 or Bk overflow over its own c_prime_range must be refused when it is loaded.
    """
    import numpy as np

    from ctdrill.model import ModelInputError, a0_n, load_calibration
    from tests.robustness.fuzz import seed_calibration

    doc = seed_calibration()
    doc["a0"] = {**doc["a0"], field: value}
    path = _write(tmp_path, "cal.json", doc)
    try:
        cal = load_calibration(path)
    except ModelInputError:
        return
    with np.errstate(all="ignore"):
        try:
            a0 = a0_n(np.array([-1000.0, 0.0, 1000.0]), 0.4, cal)
        except OverflowError:
            pytest.fail(f"a0.{field}={value} accepted, then A0 raises OverflowError")
    assert np.isfinite(a0).all(), f"a0.{field}={value} accepted, A0 = {a0}"


def _plan(**changes: object) -> dict[str, object]:
    from tests.robustness.fuzz import SEED_PLAN

    return {**json.loads(json.dumps(SEED_PLAN)), **changes}


def test_plan_with_integer_beyond_float_range_is_refused(tmp_path: Path) -> None:
    """plan-int-overflow: an integer 10**400 in ``entry_mm`` -> OverflowError (math.isfinite)."""
    from ctdrill.imaging import ImagingInputError
    from ctdrill.imaging.plan.load import load_plan

    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "p.json", _plan(entry_mm=[10**400, 0, 0])))
    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "q.json", _plan(margin_mm=10**400)))


def test_plan_with_list_as_landmark_kind_is_refused(tmp_path: Path) -> None:
    """plan-kind-unhashable: ``"kind": ["canal"]`` -> TypeError: unhashable type: 'list'."""
    from ctdrill.imaging import ImagingInputError
    from ctdrill.imaging.plan.load import load_plan

    plan = _plan()
    plan["landmarks"] = [{"name": "c", "kind": ["canal"], "points_mm": [[0, 0, 0], [1, 0, 0]]}]
    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "p.json", plan))


@pytest.mark.parametrize("name", ["junk_only", "inf_position"])
def test_cli_refusal_is_one_line_even_when_libraries_warn(
    name: str, cases: dict[str, Case]
) -> None:
    """cli-warnings-on-stderr: pydicom's UserWarning (junk file) and NumPy's RuntimeWarning
    (non-finite position) are printed on stderr before the ``error:`` line."""
    from tests.robustness.outcomes import error_line_problems, inspect_args, run_cli_subprocess

    run = run_cli_subprocess(inspect_args(cases[name]))
    assert not error_line_problems(run), error_line_problems(run)


def test_nonfinite_position_refusal_names_file_and_field(cases: dict[str, Case]) -> None:
    """inf-position-message: ``ImagePositionPatient = inf\\0\\0`` is refused with
    "CTVolume.affine_lps: expected a finite (4, 4) matrix": neither the file nor the tag."""
    from ctdrill.imaging import ImagingInputError, load_series

    with pytest.raises(ImagingInputError) as info:
        load_series(cases["inf_position"].path)
    assert "ImagePositionPatient" in str(info.value)
    assert "inf_position" in str(info.value)


def test_misaligned_file_meta_is_skipped_or_refused(tmp_path: Path) -> None:
    """dicom-bytes-length: four zero bytes inserted inside the TransferSyntaxUID value of a
    phantom slice: pydicom.errors.BytesLengthException (not a ValueError) escaped read_headers.
    The slice is the one the fuzzer mutated (a 3 x 16 x 20 phantom at 1 mm).
    """
    import io

    import pydicom
    from pydicom.errors import BytesLengthException

    from ctdrill.imaging import ImagingInputError, load_series
    from ctdrill.imaging.phantom.io import write_phantom
    from ctdrill.imaging.phantom.mandible import make_mandible_phantom
    from tests.robustness.mutate import ByteMutation, apply_bytes

    case = write_phantom(
        tmp_path / "case", make_mandible_phantom(spacing_mm=1.0, shape=(3, 16, 20))
    )
    first = sorted(Path(case.ct_dir).iterdir())[0]
    data = first.read_bytes()
    # The fuzzer's position (0.163 of the file) was one byte into the tag that follows the
    # TransferSyntaxUID value (20 bytes with its padding); the writer has written more
    # attributes since (the file is longer), so aim at that byte itself.
    inside = data.index(b"1.2.840.10008.1.2.1\x00") + 21
    mutation = ByteMutation("insert", (inside + 0.5) / len(data), 1, b"\x00" * 4)
    first.write_bytes(apply_bytes(data, mutation, []))
    with pytest.raises(BytesLengthException):  # the trigger still trips pydicom itself
        pydicom.dcmread(io.BytesIO(first.read_bytes()), stop_before_pixels=True)
    try:
        volume = load_series(case.ct_dir)
    except ImagingInputError:
        return
    assert "files_skipped" in volume.warning_codes


def _demo_plan_with(path: Path, edit: str, value: float) -> Path:
    doc = json.loads((ROOT / "assets" / "demo" / "plan.json").read_text())
    if edit == "canal":
        doc["landmarks"][0]["points_mm"][12][2] = value
    else:
        doc["entry_mm"][0] = value
    path.write_text(json.dumps(doc))
    return path


def test_plan_with_huge_canal_coordinate_is_refused_or_handled(tmp_path: Path) -> None:
    """plan-huge-coordinates: a canal point at z = 1e308 mm is accepted by load_plan, then
    imaging/_geometry.py raises ValueError (math domain error): ``ctdrill export`` exits 1."""
    from tests.robustness.outcomes import error_line_problems, run_cli_subprocess

    plan = _demo_plan_with(tmp_path / "plan.json", "canal", 1e308)
    dicom = ROOT / "assets" / "demo" / "ct"
    run = run_cli_subprocess(
        ["export", "--dicom", str(dicom), "--plan", str(plan), "--out", str(tmp_path / "out")]
    )
    assert run.code == 0 or not error_line_problems(run), run.stderr[-1500:]


def test_plan_with_huge_entry_is_refused_in_one_line(tmp_path: Path) -> None:
    """plan-huge-coordinates: ``entry_mm[0] = 1e308`` is refused ("planned depth inf mm"), but
    NumPy's "overflow encountered in dot" warning is printed on stderr first."""
    from tests.robustness.outcomes import error_line_problems, run_cli_subprocess

    plan = _demo_plan_with(tmp_path / "plan.json", "entry", 1e308)
    dicom = ROOT / "assets" / "demo" / "ct"
    run = run_cli_subprocess(
        ["export", "--dicom", str(dicom), "--plan", str(plan), "--out", str(tmp_path / "out")]
    )
    assert not error_line_problems(run), error_line_problems(run)


def test_named_pipe_in_series_folder_does_not_hang(cases: dict[str, Case]) -> None:
    """fifo-hang: ``os.mkfifo("pipe.dcm")`` beside a clean series: the loader opens the pipe and
    blocks forever. Expected: skip anything that is not a regular file (files_skipped)."""
    from tests.robustness.test_memory_bombs import check_bomb

    check_bomb(cases["fifo_in_folder"])  # also in test_memory_bombs.py; pinned here by name


@pytest.mark.parametrize(
    ("field", "value"), [("n", -1e308), ("n", -400.0), ("b0", -400.0)], ids=["n-1e308", "n", "b0"]
)
def test_calibration_whose_force_vanishes_is_refused(
    tmp_path: Path, field: str, value: float
) -> None:
    """calibration-law-vanishing: the set loads, and A0 = 0 N for every HU and feed (a material
    that cuts with no force; with n = -1e308 the evaluation overflows in ``n log10 C'`` first).
    Upper bounds are checked (laws above 1e6 N are refused); the lower end is not."""
    import numpy as np

    from ctdrill.model import ModelInputError, a0_n, load_calibration
    from tests.robustness.fuzz import seed_calibration

    doc = seed_calibration()
    doc["a0"] = {**doc["a0"], field: value}
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(doc))
    try:
        cal = load_calibration(path)
    except ModelInputError:
        return
    with np.errstate(all="ignore"):
        a0 = a0_n(np.array([-1000.0, 0.0, 1000.0]), 0.4, cal)
    pytest.fail(f"a0.{field}={value} accepted; A0 = {a0} N at HU -1000, 0, 1000")


LONG = "y" * 300  # one path component longer than NAME_MAX (255 bytes)


@pytest.mark.parametrize("where", ["inspect", "plan", "out", "calibration", "plan-calibration"])
def test_overlong_path_component_is_an_input_error(where: str, tmp_path: Path) -> None:
    """path-too-long: ``Path.is_file()``/``mkdir`` raise OSError ENAMETOOLONG (pathlib only
    swallows ENOENT-like errors), which escapes as a traceback with exit code 1."""
    from tests.robustness.outcomes import error_line_problems, run_cli_subprocess

    demo = ROOT / "assets" / "demo"
    export = ["export", "--dicom", str(demo / "ct"), "--plan", str(demo / "plan.json")]
    if where == "inspect":
        args = ["inspect", str(tmp_path / LONG), "--json"]
    elif where == "plan":
        args = ["export", "--dicom", str(demo / "ct"), "--plan", str(tmp_path / f"{LONG}.json")]
        args += ["--out", str(tmp_path / "out")]
    elif where == "out":
        args = [*export, "--out", str(tmp_path / LONG)]
    elif where == "calibration":
        args = [*export, "--out", str(tmp_path / "out"), "--calibration", LONG]
    else:
        doc = json.loads((demo / "plan.json").read_text())
        doc["calibration"] = LONG
        plan = tmp_path / "plan.json"
        plan.write_text(json.dumps(doc))
        args = ["export", "--dicom", str(demo / "ct"), "--plan", str(plan)]
        args += ["--out", str(tmp_path / "out")]
    run = run_cli_subprocess(args)
    assert not error_line_problems(run), (where, run.stderr[-800:])


def test_manifest_file_name_with_nul_byte_is_an_input_error(tmp_path: Path) -> None:
    """manifest-nul-path: ``rec\\x00.csv`` in the manifest's file column makes open() raise
    ``ValueError: embedded null byte``, which escapes read_recording (exit 1 in the CLI)."""
    from ctdrill.model import ModelInputError
    from ctdrill.model.fit import calibrate_from_manifest

    manifest = tmp_path / "manifest.csv"
    manifest.write_text("file,hu,feed_mm_s\nrec\x00.csv,-600,2\n")
    with pytest.raises(ModelInputError):
        calibrate_from_manifest(manifest, rpm=900.0, blades=2)


def _recordings_in_mn_at_one_feed(folder: Path) -> Path:
    from tests.robustness.test_fuzz_calibrate import seed_files

    for name, text in seed_files().items():
        if name.endswith("_4.csv"):  # a unit slip: these three recordings in mN
            head, *rows = text.strip().split("\n")
            scaled = [",".join([*r.split(",")[:2], f"{float(r.split(',')[2]) * 1000:.3f}"])
                      for r in rows]  # fmt: skip
            text = "\n".join([head, *scaled]) + "\n"
        (folder / name).write_text(text)
    return folder / "manifest.csv"


def test_fit_outside_the_loadable_range_is_refused_before_writing(tmp_path: Path) -> None:
    """calibrate-unloadable-fit: forces in mN at one feed fit Ke = 102696 per (mm/s); the fit
    returns it, ``ctdrill calibrate`` writes OUT.json and only then fails to load it (exit 2,
    "calibration file OUT.json: field a0.ke must be in [0, 1000]"), leaving the file behind.
    Expected: the fit refuses (naming the recordings), nothing is written."""
    from ctdrill.model.fit import calibrate_from_manifest
    from tests.robustness.outcomes import error_line_problems, run_cli_in_process

    manifest = _recordings_in_mn_at_one_feed(tmp_path)
    out = tmp_path / "out.json"
    run = run_cli_in_process(
        ["calibrate", str(manifest), "--rpm", "900", "--blades", "2", "--out", str(out)]
    )
    assert not error_line_problems(run), run.stderr
    assert not out.exists(), "an unusable calibration set was written"
    with pytest.raises(ModelInputError):
        calibrate_from_manifest(manifest, rpm=900.0, blades=2)
