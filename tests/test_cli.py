"""The ctdrill entry point: subcommands listed, usage errors follow the exit-code contract."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ctdrill.app.cli import COMMANDS, command_module, main


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


#: Modules (top-level names) that ``ctdrill --help`` and ``ctdrill COMMAND --help`` must not
#: load: the heavy numeric, DICOM, plotting, GUI and network stacks (issue 13: ``--help`` in
#: under 0.15 s). Each command imports them inside its ``run()``.
HEAVY_FOR_HELP = (
    "numpy",
    "scipy",
    "pydicom",
    "requests",
    "matplotlib",
    "vtk",
    "vtkmodules",
    "pyvista",
    "pyvistaqt",
    "PySide6",
    "serial",
    "SimpleITK",
)
#: First-party modules that building the parser may load: the CLI, its commands, the
#: ``*InputError`` modules the CLI catches (the engine's too), lazy package ``__init__`` files
#: (and ``ctdrill.lazy``, which builds their re-exports), the numpy-free defaults the parsers
#: show and ``ctdrill.interrupts`` (SIGTERM and SIGHUP taken as Ctrl-C from the start).
LIGHT_FIRST_PARTY = {
    "ctdrill",
    "ctdrill.app",
    "ctdrill.app.cli",
    "ctdrill.app.commands",
    "ctdrill.app.commands.options",
    "ctdrill.app.errors",
    "ctdrill.app.search",
    "ctdrill.app.search.defaults",
    "ctdrill.engine",
    "ctdrill.engine.errors",
    "ctdrill.engine.settings",
    "ctdrill.haptics",
    "ctdrill.haptics.errors",
    "ctdrill.imaging",
    "ctdrill.imaging.errors",
    "ctdrill.imaging.phantom",
    "ctdrill.imaging.phantom.classes",
    "ctdrill.imaging.plan",
    "ctdrill.imaging.plan.budget",  # stdlib only: --placement's choices
    "ctdrill.imaging.stack",
    "ctdrill.interrupts",
    "ctdrill.lazy",
    "ctdrill.model",
    "ctdrill.model.errors",
    "ctdrill.model.fit_defaults",
}


def _modules_imported_by(argv: list[str]) -> set[str]:
    """Every module in ``sys.modules`` after ``ctdrill ARGV`` ran in a fresh interpreter."""
    code = (
        "import json, sys\n"
        "from ctdrill.app.cli import main\n"
        "try:\n"
        f"    main({argv!r})\n"
        "except SystemExit:\n"
        "    pass\n"
        "sys.stderr.write(json.dumps(sorted(sys.modules)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "usage: ctdrill" in out.stdout
    names = set(json.loads(out.stderr))
    # the parser was built: every command's for ``--help``, the command's own for ``CMD ...``
    built = command_module(argv[0]) if argv[0] in COMMANDS else "inspect"
    assert f"ctdrill.app.commands.{built}" in names
    if argv[0] in COMMANDS and argv[0] != "inspect":
        assert "ctdrill.app.commands.inspect" not in names  # only its own command's module
    return names


@pytest.mark.parametrize("argv", [["--help"]] + [[name, "--help"] for name in COMMANDS])
def test_help_imports_no_heavy_module(argv: list[str]) -> None:
    names = _modules_imported_by(argv)
    heavy = sorted(n for n in names if n.split(".")[0] in HEAVY_FOR_HELP)
    assert heavy == []
    first_party = {n for n in names if n.split(".")[0] == "ctdrill"}
    assert (
        first_party - {f"ctdrill.app.commands.{command_module(c)}" for c in COMMANDS}
        <= LIGHT_FIRST_PARTY
    )
