"""Unreadable files and subfolders of a series: warned (``files_unreadable``), never silent.

Permissions do not bind root, so each case runs the loader in a subprocess that drops to the
``nobody`` user (``os.setuid``) after importing everything, on a series written by the tests'
corpus builder (10 x 12 x 8, slice k at z = k mm).
"""

from __future__ import annotations

import json
import os
import pwd
import shutil
import subprocess
import sys
import tempfile
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.robustness.corpus_base import base_slices, write, write_all

LOADER = textwrap.dedent(
    """
    import json, os, sys
    from pathlib import Path
    from ctdrill.imaging import ImagingInputError, load_series
    folder, uid = Path(sys.argv[1]), int(sys.argv[2])
    load_series(folder)  # import every module while root can still read the interpreter's
    for spec in sys.argv[3:]:
        os.chmod(folder / spec, 0)
    if os.geteuid() == 0:
        os.setgid(uid)
        os.setuid(uid)
    try:
        vol = load_series(folder)
    except ImagingInputError as exc:
        print(json.dumps({"error": str(exc)}))
    else:
        print(json.dumps({
            "dims": [int(vol.hu.shape[2]), int(vol.hu.shape[1]), int(vol.hu.shape[0])],
            "warnings": {w.code: w.message for w in vol.warnings},
        }))
    """
)


@pytest.fixture
def series() -> Iterator[Path]:
    """The series in a folder every user may enter (pytest's tmp folders are root's only)."""
    top = Path(tempfile.mkdtemp(prefix="ctdrill-unreadable-"))
    os.chmod(top, 0o755)
    folder = top / "ct"
    slices = base_slices(series="unreadable")
    paths = write_all(slices[:6], folder)
    write(slices[6], folder / "IM0006")
    write(slices[7], folder / "sub" / "IM0007")
    for p in [folder, folder / "sub"]:
        os.chmod(p, 0o755)
    for p in [*paths, folder / "IM0006", folder / "sub" / "IM0007"]:
        os.chmod(p, 0o644)
    try:
        yield folder
    finally:
        for root, dirs, _ in os.walk(top):
            for d in dirs:
                os.chmod(Path(root) / d, 0o755)
        shutil.rmtree(top)


def _load(folder: Path, *unreadable: str) -> dict[str, object]:
    nobody = pwd.getpwnam("nobody").pw_uid
    proc = subprocess.run(
        [sys.executable, "-c", LOADER, str(folder), str(nobody), *unreadable],
        capture_output=True,
        text=True,
        timeout=120,
        cwd="/",
    )
    assert proc.returncode == 0, proc.stderr
    result: dict[str, object] = json.loads(proc.stdout)
    return result


def test_all_readable_loads_clean(series: Path) -> None:
    assert _load(series) == {"dims": [10, 12, 8], "warnings": {}}


def test_an_unreadable_file_and_subfolder_at_the_end_are_counted(series: Path) -> None:
    got = _load(series, "IM0006", "sub")
    assert got["dims"] == [10, 12, 6]
    assert got["warnings"] == {
        "files_unreadable": "2 file(s) or folder(s) could not be read (permission denied or an "
        "I/O error), e.g. sub: the series may be incomplete; check the permissions and load again"
    }


def test_an_unreadable_folder_is_refused_saying_why(series: Path) -> None:
    got = _load(series.parent, "ct")
    message = str(got["error"])
    assert "no CT image series" in message
    assert "1 file(s) or folder(s) could not be read" in message and "e.g. ct " in message


def test_an_unreadable_middle_slice_is_a_gap_and_says_why(series: Path) -> None:
    """Slice 3 unreadable: the stack has a 2 mm step among 1 mm ones. The loader reports the
    gap as for any missing slice (a drill path crossing it is then refused), and why."""

    names = sorted(p.name for p in series.iterdir() if p.name.startswith("IM0") and p.is_file())
    # write_all names slice k "IM%04d" % (k * 7919 % 1000): slice 3 is IM0757
    assert "IM0757" in names
    got = _load(series, "IM0757")
    assert got["dims"] == [10, 12, 7]
    warnings = got["warnings"]
    assert isinstance(warnings, dict)
    assert set(warnings) == {"slice_gap", "files_unreadable"}
    assert warnings["files_unreadable"].startswith("1 file(s) or folder(s) could not be read")
