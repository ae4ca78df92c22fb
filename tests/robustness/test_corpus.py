"""Every hard input of the corpus meets its expected outcome, in the loader and in the CLI.

Resource hazards (memory bombs, special files) run in ``test_memory_bombs.py`` (in a child
process under an address-space limit and a timeout); the cases that
show a bug live in ``test_found_bugs.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.robustness.checks import check_inspect, check_load
from tests.robustness.make_corpus import SYNTHETIC, Case, case_names
from tests.robustness.outcomes import error_line_problems, inspect_args, run_cli_subprocess
from tests.robustness.test_found_bugs import BUG_CASES

ISOLATED = {name for name, (_, _, isolate) in SYNTHETIC.items() if isolate}
NAMES = [n for n in case_names() if n not in ISOLATED and n not in BUG_CASES]


@pytest.mark.parametrize("name", NAMES)
def test_case_outcome_in_loader_and_cli(name: str, cases: dict[str, Case]) -> None:
    case = cases[name]
    seen = check_load(case)
    check_inspect(case, seen)


def test_corpus_covers_every_fault_family(cases: dict[str, Case]) -> None:
    faults = {case.fault for case in cases.values()}
    for family in (
        "truncated file",
        "short PixelData",
        "missing geometry",
        "duplicates",
        "gaps and spacing",
        "two series",
        "localizer",
        "junk and non-image files",
        "DICOMDIR",
        "memory bomb",
        "wrong VR",
        "colour claiming HU",
    ):
        assert family in faults
    assert sum(case.real for case in cases.values()) >= 10
    assert all(case.path.exists() for case in cases.values() if case.name != "no_such_dir")


def test_max_bytes_refuses_a_series_larger_than_allowed(cases: dict[str, Case]) -> None:
    from ctdrill.imaging import ImagingInputError, load_series

    with pytest.raises(ImagingInputError):
        load_series(cases["clean"].path, max_bytes=1000)  # the series holds 1920 bytes of HU
    assert load_series(cases["clean"].path, max_bytes=10_000).dims == (10, 12, 8)


@pytest.mark.parametrize(
    "name", ["clean", "missing_ipp", "no_such_dir", "duplicate_conflicting", "truncated_pixels"]
)
def test_console_script_sample(name: str, cases: dict[str, Case], tmp_path: Path) -> None:
    """The installed entry point behaves as the in-process one (one line, exit 2, no traceback)."""
    case = cases[name]
    run = run_cli_subprocess(inspect_args(case))
    if case.expected[0].outcome == "refuse":
        assert not error_line_problems(run), error_line_problems(run)
        assert run.stdout == ""
    else:
        assert run.code == 0, run.stderr
        assert run.json()["dims"] == [10, 12, 8]
        assert run.stderr == ""
