"""Resource hazards are handled cleanly in a child process with an address-space cap and a timeout.

Memory bombs (declared sizes far beyond the data) must be refused; special files in a series
folder (a named pipe, symlinks to /dev/zero and /dev/urandom) must neither block nor be read
forever. Each case runs ``ctdrill inspect --json`` in a fresh process whose ``RLIMIT_AS`` is
2 GiB: the import of the CLI and a real load need about 0.4 GiB of address space (VmPeak
378 MB measured), while every bomb declares tens of GiB or more. A ``MemoryError`` (a
traceback), a hang (no answer within 15 s) or an outcome the case does not accept fails.
"""

from __future__ import annotations

import subprocess

import pytest

from tests.robustness.make_corpus import SYNTHETIC, Case
from tests.robustness.outcomes import error_line_problems, inspect_args, run_cli_subprocess
from tests.robustness.test_found_bugs import BUG_CASES

#: Address-space cap of the process that loads a bomb, bytes.
BOMB_ADDRESS_SPACE = 2 << 30
#: A child that has not answered by then is hung.
HANG_S = 15.0
ISOLATED = [n for n, (_, _, isolate) in SYNTHETIC.items() if isolate and n not in BUG_CASES]


def check_bomb(case: Case) -> None:
    """Run the case under the cap and assert a clean refusal (or an acceptable reported load)."""
    try:
        run = run_cli_subprocess(
            inspect_args(case), address_space_bytes=BOMB_ADDRESS_SPACE, timeout_s=HANG_S
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"{case.name}: ctdrill inspect hung (no exit within {HANG_S:.0f} s)")
    assert "MemoryError" not in run.stderr, run.stderr[-3000:]
    assert "Traceback" not in run.stderr, run.stderr[-3000:]
    if run.code == 0:
        doc = run.json()
        codes = sorted(w["code"] for w in doc["warnings"])
        assert any(e.accepts_load(codes, doc["dims"]) for e in case.expected), (
            f"{case.name}: loaded {doc['dims']} with {codes}; expected "
            + " | ".join(e.describe() for e in case.expected)
        )
        return
    assert not error_line_problems(run), error_line_problems(run)


def test_cap_leaves_room_for_a_real_load(cases: dict[str, Case]) -> None:
    """The cap is not what refuses: the clean series loads under the same limit."""
    run = run_cli_subprocess(inspect_args(cases["clean"]), address_space_bytes=BOMB_ADDRESS_SPACE)
    assert run.code == 0, run.stderr
    assert run.json()["dims"] == [10, 12, 8]


@pytest.mark.parametrize("name", ISOLATED)
def test_hazard_is_handled_under_address_space_cap_and_timeout(
    name: str, cases: dict[str, Case]
) -> None:
    check_bomb(cases[name])
