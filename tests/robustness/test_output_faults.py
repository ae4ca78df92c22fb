"""Outputs under a full disk, a file-size limit and a kill: ``calibrate --out`` and ``export``.

Each case runs the real CLI in a subprocess: a 1 MiB tmpfs in a private mount namespace
(``unshare -m``; ``-rm`` when not root) for the full disk, ``RLIMIT_FSIZE`` for the size limit.
The previous output must survive byte for byte, the error must be one ``error:`` line naming
the file, and nothing may be left beside it.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.conftest import ASSETS
from tests.model.synth import write_campaign

DEMO = ASSETS / "demo"
CALIBRATE = ["calibrate", "--rpm", "900", "--blades", "2", "--depth-window-mm", "1", "3"]


@pytest.fixture(scope="module")
def manifest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_campaign(tmp_path_factory.mktemp("campaign"))


def _cli(
    argv: list[str], *, fsize: int | None = None, prefix: tuple[str, ...] = ()
) -> tuple[int, str, str]:
    def limit() -> None:
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [*prefix, sys.executable, "-m", "ctdrill.app.cli", *argv],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=limit,
        env=env,
    )
    return proc.returncode, proc.stdout, proc.stderr


def _one_error(err: str) -> str:
    assert err.startswith("error: ") and err.count("\n") == 1, err
    return err


def test_calibrate_out_under_a_file_size_limit_keeps_the_old_set(
    manifest: Path, tmp_path: Path
) -> None:
    out = tmp_path / "cal.json"
    code, _, err = _cli([*CALIBRATE, str(manifest), "--out", str(out)])
    assert code == 0, err
    good = out.read_bytes()
    assert len(good) > 1500
    code, _, err = _cli([*CALIBRATE, str(manifest), "--out", str(out)], fsize=1000)
    assert code == 2
    assert _one_error(err) == (
        f"error: --out {out}: cannot write it: the file exceeds the file-size limit "
        "(ulimit -f / RLIMIT_FSIZE); raise the limit or write elsewhere\n"
    )
    assert out.read_bytes() == good and sorted(os.listdir(tmp_path)) == ["cal.json"]


FULL_DISK_CALIBRATE = textwrap.dedent(
    """
    set -e
    mount -t tmpfs -o size=1m tmpfs "$1"
    shift
    "$@" --out "$DISK/cal.json" > /dev/null
    cp "$DISK/cal.json" "$DISK/good.json"
    # fill the disk, leaving less room than a new set needs
    dd if=/dev/zero of="$DISK/filler" bs=1k count=2000 2> /dev/null || true
    set +e
    "$@" --out "$DISK/cal.json"
    echo "exit $?"
    cmp "$DISK/cal.json" "$DISK/good.json" && echo same
    ls -a "$DISK"
    """
)


def test_calibrate_out_on_a_full_disk_keeps_the_old_set(manifest: Path, tmp_path: Path) -> None:
    """The issue's case: a good set overwritten in place became 8 KB of invalid JSON."""
    disk = tmp_path / "disk"
    disk.mkdir()
    ns = ["unshare", "-m"] if os.geteuid() == 0 else ["unshare", "-rm"]
    cmd = [sys.executable, "-m", "ctdrill.app.cli", *CALIBRATE, str(manifest)]
    proc = subprocess.run(
        [*ns, "sh", "-c", FULL_DISK_CALIBRATE, "sh", str(disk), *cmd],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "DISK": str(disk), "PYTHONDONTWRITEBYTECODE": "1"},
    )
    out = disk / "cal.json"
    assert proc.stderr == (
        f"error: --out {out}: cannot write it: the disk is full (or the quota is used up); "
        "free space or write elsewhere\n"
    )
    lines = proc.stdout.splitlines()
    assert lines[:2] == ["exit 2", "same"], proc.stdout
    assert lines[2:] == [".", "..", "cal.json", "filler", "good.json"]


def _export(out: Path, *, fsize: int | None = None, rate_hz: str = "1000") -> tuple[int, str]:
    argv = ["export", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    code, _, err = _cli([*argv, "--out", str(out), "--rate-hz", rate_hz], fsize=fsize)
    return code, err


def test_export_under_a_file_size_limit_keeps_the_old_export_whole(tmp_path: Path) -> None:
    out = tmp_path / "out"
    code, err = _export(out, rate_hz="100")
    assert code == 0, err
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert sorted(before) == ["force.csv", "force.png", "profile.csv", "summary.json"]
    # at 1000 Hz force.csv holds ~27000 rows (> 1 MB): the limit stops it
    code, err = _export(out, fsize=1_000_000)
    assert code == 2
    assert _one_error(err) == (
        f"error: {out / 'force.csv'}: cannot write it: the file exceeds the file-size limit "
        "(ulimit -f / RLIMIT_FSIZE); raise the limit or write elsewhere\n"
    )
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_export_refuses_to_replace_a_folder_of_other_files(tmp_path: Path) -> None:
    out = tmp_path / "Desktop"
    out.mkdir()
    (out / "notes.txt").write_text("mine", encoding="utf-8")
    code, err = _export(out, rate_hz="100")
    assert code == 2
    assert "notes.txt" in _one_error(err) and "choose a new or empty folder" in err
    assert os.listdir(out) == ["notes.txt"] and sorted(os.listdir(tmp_path)) == ["Desktop"]
