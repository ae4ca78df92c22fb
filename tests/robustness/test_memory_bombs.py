"""Memory bombs (declared sizes far beyond the data) are refused cleanly under an address-space cap.

Each case runs ``ctdrill inspect --json`` in a fresh process whose ``RLIMIT_AS`` is 2 GiB: the
import of the CLI and a real load need about 0.4 GiB of address space (VmPeak 378 MB measured),
while every bomb declares tens of GiB or more. A ``MemoryError`` (a traceback) or an exit code
other than 2 fails; so does a load.
"""

from __future__ import annotations

import pytest

from tests.robustness.make_corpus import SYNTHETIC, Case
from tests.robustness.outcomes import error_line_problems, inspect_args, run_cli_subprocess
from tests.robustness.test_found_bugs import BUG_CASES

#: Address-space cap of the process that loads a bomb, bytes.
BOMB_ADDRESS_SPACE = 2 << 30
BOMBS = [n for n, (_, _, bomb) in SYNTHETIC.items() if bomb and n not in BUG_CASES]


def check_bomb(case: Case) -> None:
    """Run the case under the cap and assert a clean refusal (or an acceptable reported load)."""
    run = run_cli_subprocess(inspect_args(case), address_space_bytes=BOMB_ADDRESS_SPACE)
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


@pytest.mark.parametrize("name", BOMBS)
def test_memory_bomb_is_refused_under_address_space_cap(name: str, cases: dict[str, Case]) -> None:
    check_bomb(cases[name])
