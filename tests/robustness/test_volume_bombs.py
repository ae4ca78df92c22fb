"""Volume-file bombs through the CLI, in a fresh process capped at 2 GiB of address space.

One bomb per format of ``tests/imaging/hostile_volumes.py`` (gzip and zlib streams inflating far
past their header, a header declaring terabytes) is given to ``ctdrill inspect --ct`` as a CT,
and the NRRD gzip bomb to ``ctdrill export`` as a plan's mask: one ``error:`` line, exit 2, no
MemoryError or traceback, within :data:`HANG_S`. Every bomb of that module is refused in bounded
memory through the Python API too (``tests/imaging/test_volume_hostile.py``, traced peak).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from tests.conftest import ASSETS
from tests.imaging.hostile_volumes import BOMBS, HOSTILE
from tests.robustness.outcomes import error_line_problems, run_cli_subprocess
from tests.robustness.test_memory_bombs import BOMB_ADDRESS_SPACE, HANG_S


def _run(args: list[str]) -> None:
    try:
        run = run_cli_subprocess(args, address_space_bytes=BOMB_ADDRESS_SPACE, timeout_s=HANG_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"ctdrill {args[0]} hung (no exit within {HANG_S:.0f} s)")
    assert not error_line_problems(run), error_line_problems(run)


#: One per format, and the header declaring terabytes (each case costs a fresh process).
CLI_BOMBS = ("nifti_gz_bomb", "nrrd_gzip_bomb", "mha_zlib_bomb", "nifti_huge_dims")


@pytest.mark.parametrize("name", CLI_BOMBS)
def test_ct_bomb_is_one_error_line_under_the_cap(tmp_path: Path, name: str) -> None:
    path, _ = HOSTILE[name](tmp_path)
    _run(["inspect", "--ct", str(path), "--json"])


def test_mask_bomb_is_one_error_line_under_the_cap(tmp_path: Path) -> None:
    assert set(CLI_BOMBS) <= set(BOMBS)
    path, _ = HOSTILE["nrrd_gzip_bomb"](tmp_path)
    doc = json.loads((ASSETS / "demo" / "plan.json").read_text())
    doc["landmarks"] = [{"name": "canal", "kind": "mask", "path": str(path)}]
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(doc))
    _run(
        [
            "export",
            "--ct",
            str(ASSETS / "demo" / "ct"),
            "--plan",
            str(plan),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert not (tmp_path / "out").exists()
