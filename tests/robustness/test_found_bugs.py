"""Bugs found by the robustness tests, each a failing test until fixed (docs/robustness.md).

``KNOWN_BUGS`` lists the signature (exception type and the project function it escapes from) of
each bug whose trigger the fuzzers keep hitting: the fuzz tests tolerate exactly these and fail on
anything new, while the tests below pin each bug with its minimal input. ``BUG_CASES`` are corpus
cases whose outcome is wrong; ``test_corpus.py`` leaves them to this module.
"""

from __future__ import annotations

import json
import traceback
from dataclasses import dataclass
from pathlib import Path

import pytest
from pydicom.errors import BytesLengthException

from tests.robustness.make_corpus import ROOT, Case


@dataclass(frozen=True)
class KnownBug:
    """A reported bug: ``exc_type`` escaping from ``function`` (``*``: any) in ``module_path``."""

    key: str
    exc_type: type[BaseException]
    module_path: str
    function: str


KNOWN_BUGS: tuple[KnownBug, ...] = (
    KnownBug("plan-int-overflow", OverflowError, "imaging/plan.py", "number"),
    KnownBug("plan-int-overflow", OverflowError, "imaging/plan.py", "point"),
    KnownBug("plan-kind-unhashable", TypeError, "imaging/plan.py", "_parse_landmark"),
    KnownBug(
        "dicom-unknown-transfer-syntax", ValueError, "imaging/pixels.py", "decoder_plugin_for"
    ),
    # Any header accessor of the loader: pydicom converts values lazily and raises then.
    KnownBug("dicom-unknown-vr", NotImplementedError, "imaging/discovery.py", "*"),
    KnownBug("dicom-bytes-length", BytesLengthException, "imaging/discovery.py", "*"),
    KnownBug("dicom-header-unbounded-read", MemoryError, "imaging/discovery.py", "read_headers"),
)

#: Corpus cases whose outcome is wrong (kept out of test_corpus.py, asserted below).
BUG_CASES: frozenset[str] = frozenset(
    {
        "zero_rescale_slope",
        "bomb_number_of_frames",
        "bomb_pixel_length_all",
        "bomb_pixel_length_one",
        "bomb_header_element_length",
        "private_transfer_syntax",
        "unknown_vr",
    }
)


def known_bug(exc: BaseException) -> str | None:
    """The key of the reported bug ``exc`` comes from, or None if it is a new one."""
    frames = [
        f
        for f in traceback.extract_tb(exc.__traceback__)
        if Path(f.filename).is_relative_to(ROOT)
        and "/tests/" not in f.filename
        and "/.venv/" not in f.filename
    ]
    while frames and frames[-1].name.startswith("<"):  # <genexpr>, <listcomp>, <lambda>
        frames.pop()
    if not frames:
        return None
    where = frames[-1]
    rel = Path(where.filename).relative_to(ROOT).as_posix()
    for bug in KNOWN_BUGS:
        if (
            isinstance(exc, bug.exc_type)
            and rel == bug.module_path
            and bug.function in (where.name, "*")
        ):
            return bug.key
    return None


def _write(tmp_path: Path, name: str, doc: object) -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def _plan(**changes: object) -> dict[str, object]:
    from tests.robustness.fuzz import SEED_PLAN

    return {**json.loads(json.dumps(SEED_PLAN)), **changes}


def test_plan_with_integer_beyond_float_range_is_refused(tmp_path: Path) -> None:
    """plan-int-overflow: an integer 10**400 in ``entry_mm`` -> OverflowError (math.isfinite)."""
    from imaging import ImagingInputError
    from imaging.plan import load_plan

    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "p.json", _plan(entry_mm=[10**400, 0, 0])))
    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "q.json", _plan(margin_mm=10**400)))


def test_plan_with_list_as_landmark_kind_is_refused(tmp_path: Path) -> None:
    """plan-kind-unhashable: ``"kind": ["canal"]`` -> TypeError: unhashable type: 'list'."""
    from imaging import ImagingInputError
    from imaging.plan import load_plan

    plan = _plan()
    plan["landmarks"] = [{"name": "c", "kind": ["canal"], "points_mm": [[0, 0, 0], [1, 0, 0]]}]
    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "p.json", plan))


@pytest.fixture(scope="module")
def bug_cases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Case]:
    from tests.robustness.checks import corpus_cases

    return corpus_cases(tmp_path_factory.mktemp("corpus"))


@pytest.mark.parametrize("name", sorted(BUG_CASES))
def test_corpus_case_with_wrong_outcome(name: str, bug_cases: dict[str, Case]) -> None:
    """Corpus cases the loader gets wrong (details in docs/robustness.md, "Found bugs").

    * zero_rescale_slope: RescaleSlope 0 maps every voxel to the intercept; loads silently.
    * bomb_number_of_frames: NumberOfFrames 2147483647 with one frame of data; loads one slice.
    * bomb_pixel_length_all / _one: PixelData declares 4294967280 bytes in a 1 kB file (an
      incomplete copy); loads silently, while a shorter truncation is refused.
    * bomb_header_element_length: a header element declaring 4294967280 bytes makes pydicom
      allocate that much: MemoryError traceback under an address-space limit.
    * private_transfer_syntax: TransferSyntaxUID 1.2.840.12008.1.2.1 (one bit off explicit VR
      little endian): ValueError "UID is not a transfer syntax." from decoder_plugin_for.
    * unknown_vr: SliceThickness with the VR bytes "D[": NotImplementedError "Unknown Value
      Representation" from pydicom's lazy conversion inside imaging/discovery.py.
    """
    from tests.robustness.checks import check_inspect, check_load
    from tests.robustness.test_memory_bombs import check_bomb

    case = bug_cases[name]
    if case.memory_bomb:
        check_bomb(case)
    else:
        check_inspect(case, check_load(case))


@pytest.mark.parametrize("name", ["junk_only", "inf_position"])
def test_cli_refusal_is_one_line_even_when_libraries_warn(
    name: str, bug_cases: dict[str, Case]
) -> None:
    """cli-warnings-on-stderr: pydicom's UserWarning (junk file) and NumPy's RuntimeWarning
    (non-finite position) are printed on stderr before the ``error:`` line."""
    from tests.robustness.outcomes import error_line_problems, inspect_args, run_cli_subprocess

    run = run_cli_subprocess(inspect_args(bug_cases[name]))
    assert not error_line_problems(run), error_line_problems(run)


def test_nonfinite_position_refusal_names_file_and_field(bug_cases: dict[str, Case]) -> None:
    """inf-position-message: ``ImagePositionPatient = inf\\0\\0`` is refused with
    "CTVolume.affine_lps: expected a finite (4, 4) matrix": neither the file nor the tag."""
    from imaging import ImagingInputError, load_series

    with pytest.raises(ImagingInputError) as info:
        load_series(bug_cases["inf_position"].path)
    assert "ImagePositionPatient" in str(info.value)
    assert "inf_position" in str(info.value)


def test_misaligned_file_meta_is_skipped_or_refused() -> None:
    """dicom-bytes-length: four zero bytes inserted inside the TransferSyntaxUID value of a
    phantom slice: pydicom.errors.BytesLengthException (not a ValueError) escapes read_headers.
    """
    from tests.robustness.mutate import ByteMutation
    from tests.robustness.test_fuzz_dicom import check_mutated_series

    mutation = ByteMutation("insert", 0.1630122888807033, 1, b"\x00" * 4)
    assert check_mutated_series("phantom", 0, [mutation]) in ("load", "refuse")
