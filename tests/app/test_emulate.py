"""``ctdrill emulate``: link creation and clean-up, refusals."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from ctdrill.app.cli import main


def test_emulate_runs_for_a_duration_and_removes_its_link(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    link = tmp_path / "dev"
    assert main(["emulate", "--pty-link", str(link), "--duration-s", "0.3"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"emulating on {link} -> /dev/pts/")
    assert "emulator stopped" in err
    ticks = int(err.split("emulator stopped: ")[1].split(" ticks")[0])
    assert 1_500 < ticks <= 3_100  # 0.3 s at 10 kHz device time (minus start-up)
    assert not os.path.lexists(link)


def test_emulate_replaces_a_stale_link(tmp_path: Path) -> None:
    link = tmp_path / "dev"
    link.symlink_to("/dev/pts/does-not-exist")
    assert main(["emulate", "--pty-link", str(link), "--duration-s", "0.05"]) == 0
    assert not os.path.lexists(link)


@pytest.mark.parametrize("kind", ["file", "missing-dir"])
def test_emulate_refuses_a_bad_link_path(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    path = tmp_path / "regular"
    if kind == "file":
        path.write_text("keep me")
    else:
        path = tmp_path / "no" / "such" / "dir" / "dev"
    assert main(["emulate", "--pty-link", str(path), "--duration-s", "0.05"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "--pty-link" in err and "Traceback" not in err
    if kind == "file":
        assert path.read_text() == "keep me"


@pytest.mark.parametrize(
    "args", [["--duration-s", "nan"], ["--duration-s", "-1"], ["--start-mm", "inf"]]
)
def test_emulate_refuses_bad_numbers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str]
) -> None:
    assert main(["emulate", "--pty-link", str(tmp_path / "dev"), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --") and not os.path.lexists(tmp_path / "dev")
