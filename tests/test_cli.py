"""The ctdrill entry point: subcommands listed, usage errors follow the exit-code contract."""

from __future__ import annotations

import subprocess
import sys

import pytest

from ctdrill.app.cli import COMMANDS, main


def test_help_lists_every_subcommand(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out


def test_console_script_runs() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "ctdrill.app.cli", "--help"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "inspect" in out.stdout


def test_unknown_subcommand_is_exit_2_with_error_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["no-such-command"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error:")
    assert "Traceback" not in err


def test_an_os_refusal_of_a_path_is_exit_2_naming_it(
    tmp_path: object, capsys: pytest.CaptureFixture[str]
) -> None:
    too_long = f"{tmp_path}/{'y' * 300}"  # one component over NAME_MAX: ENAMETOOLONG
    assert main(["inspect", too_long, "--json"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
    assert "y" * 300 in err and "Traceback" not in err
