"""Observe what the loader and ``ctdrill inspect`` do with a case (shared by tests and report)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tests.robustness.make_corpus import ROOT, Case

#: The project's own bad-input types: the only exceptions bad input may raise.
PROJECT_ERRORS: tuple[str, ...] = (
    "ImagingInputError",
    "ModelInputError",
    "HapticsInputError",
    "AppInputError",
)


@dataclass(frozen=True)
class Observed:
    """What happened when a case was loaded.

    Attributes
    ----------
    outcome : "load", "refuse" (an ``ImagingInputError``) or "bug" (any other exception).
    codes : warning codes of a load, sorted.
    dims : (cols, rows, slices) of a load.
    message : the error message of a refusal, or the exception text of a bug.
    seconds : wall time of the call, s.
    """

    outcome: str
    codes: tuple[str, ...] = ()
    dims: tuple[int, ...] = ()
    message: str = ""
    seconds: float = 0.0


def observe_load(case: Case) -> Observed:
    """Call ``ctdrill.imaging.load_series`` on the case and classify the result."""
    from ctdrill.imaging import ImagingInputError, load_series

    start = time.perf_counter()
    try:
        if case.series_uid is None:
            volume = load_series(case.path)
        else:
            volume = load_series(case.path, series_uid=case.series_uid)
    except ImagingInputError as exc:
        return Observed("refuse", message=str(exc), seconds=time.perf_counter() - start)
    except Exception as exc:  # a bug: classified, the test reports it
        return Observed("bug", message=repr(exc), seconds=time.perf_counter() - start)
    return Observed(
        "load",
        codes=tuple(sorted(w.code for w in volume.warnings)),
        dims=tuple(int(d) for d in volume.dims),
        seconds=time.perf_counter() - start,
    )


def inspect_args(case: Case) -> list[str]:
    """``ctdrill`` arguments that inspect the case as JSON."""
    args = ["inspect", str(case.path), "--json"]
    return args + (["--series", case.series_uid] if case.series_uid else [])


@dataclass(frozen=True)
class CliRun:
    """Exit code and output of one ``ctdrill`` run."""

    code: int
    stdout: str
    stderr: str

    def json(self) -> dict[str, Any]:
        """The JSON document on stdout."""
        doc: dict[str, Any] = json.loads(self.stdout)
        return doc


def run_cli_in_process(args: list[str]) -> CliRun:
    """Run ``ctdrill.app.cli.main(args)`` capturing stdout/stderr; exceptions propagate (bugs)."""
    from ctdrill.app.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(args)
        except SystemExit as exc:  # argparse usage errors
            code = int(exc.code) if isinstance(exc.code, int) else 1
    return CliRun(code, out.getvalue(), err.getvalue())


#: Runs ``ctdrill`` under an address-space limit (bytes in argv[1]); the rest is its argv.
_LIMITED = """
import resource, sys
limit = int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
from ctdrill.app.cli import main
sys.exit(main(sys.argv[2:]))
"""


def run_cli_subprocess(
    args: list[str], *, address_space_bytes: int | None = None, timeout_s: float = 60.0
) -> CliRun:
    """Run ``python -m app.cli`` (optionally under ``RLIMIT_AS``) in a fresh process."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if address_space_bytes is None:
        argv = [sys.executable, "-m", "ctdrill.app.cli", *args]
    else:
        argv = [sys.executable, "-c", _LIMITED, str(address_space_bytes), *args]
    proc = subprocess.run(
        argv, capture_output=True, text=True, timeout=timeout_s, cwd=ROOT, env=env, check=False
    )
    return CliRun(proc.returncode, proc.stdout, proc.stderr)


def error_line_problems(run: CliRun) -> list[str]:
    """Ways a refusal breaks the contract: exit 2, exactly one ``error:`` line, no traceback."""
    problems = []
    if run.code != 2:
        problems.append(f"exit code {run.code}, expected 2")
    lines = run.stderr.splitlines()
    if len(lines) != 1 or not lines[0].startswith("error: "):
        problems.append(f"stderr is not one 'error: ...' line: {run.stderr[-2000:]!r}")
    if "Traceback" in run.stderr or "MemoryError" in run.stderr:
        problems.append("traceback on stderr")
    return problems


def folder_files(path: Path) -> list[Path]:
    """Regular files below ``path`` (not following symlinks)."""
    if not path.is_dir():
        return []
    return sorted(p for p in path.rglob("*") if p.is_file() and not p.is_symlink())
