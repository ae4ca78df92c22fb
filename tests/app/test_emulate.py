"""``ctdrill emulate``: link creation and clean-up, refusals."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from ctdrill.haptics.realtime import link_lock_path
from ctdrill.haptics.serial_device import SerialDevice
from tests.haptics.emulator_process import ROOT, emulator_process, spawn_emulator


def _emulate(link: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    """A second ``ctdrill emulate`` on ``link``, in its own process, to its end."""
    return subprocess.run(
        [sys.executable, "-m", "ctdrill.app.cli", "emulate", "--pty-link", str(link), *extra],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


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


@pytest.mark.timeout(120)
def test_a_second_emulator_does_not_take_a_running_emulators_link(tmp_path: Path) -> None:
    # Two real emulator processes on one path: the second is refused with one error line
    # naming the first (exit 2, in bounded time: it never starts serving), and the first keeps
    # its link, its lock and its host: a session still reaches it through the link.
    link = tmp_path / "dev"
    with emulator_process(link) as first:
        pty = os.readlink(link)
        assert link_lock_path(link).read_text().split() == [str(first.pid), pty]
        second = _emulate(link, "--duration-s", "5")
        err = second.stderr.strip().splitlines()
        assert second.returncode == 2 and len(err) == 1, second.stderr
        assert err[0].startswith(f"error: --pty-link {link}: a running emulator (pid {first.pid})")
        assert second.stdout == "" and "Traceback" not in second.stderr
        assert os.readlink(link) == pty and link_lock_path(link).exists()
        device = SerialDevice(str(link))
        try:
            assert device.hello().limits.peak_force_n == 78.0
        finally:
            device.close()
    assert not os.path.lexists(link_lock_path(link))  # the first removed its lock on exit


def test_a_link_to_a_pty_in_use_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # No lock beside it (an emulator of an older version, or another program): the link's pty
    # is held open by this process, so the link is live and is left alone.
    master, slave = os.openpty()
    try:
        link = tmp_path / "dev"
        link.symlink_to(os.ttyname(slave))
        assert main(["emulate", "--pty-link", str(link), "--duration-s", "0.05"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"error: --pty-link {link}: links to /dev/pts/")
        assert "a terminal that a running program holds open" in err[0]
        assert os.readlink(link) == os.ttyname(slave)
        assert not os.path.lexists(link_lock_path(link))
        # the same link beside a dead emulator's lock naming that pty: the number was given
        # to another program after the emulator died; its link is stale and is replaced
        link_lock_path(link).write_text(f"999999999 {os.ttyname(slave)}\n")
        assert main(["emulate", "--pty-link", str(link), "--duration-s", "0.05"]) == 0
        assert not os.path.lexists(link) and not os.path.lexists(link_lock_path(link))
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.timeout(120)
def test_a_killed_emulators_link_and_lock_are_taken_over(tmp_path: Path) -> None:
    # kill -9 leaves the link (its pty closed with the process, its number free for any
    # program's next pty) and the lock file naming that pty (its lock released by the kernel):
    # both stale, a new emulator replaces them and runs.
    link = tmp_path / "dev"
    proc = spawn_emulator(link)
    pty = os.readlink(link)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=10)
    assert link.is_symlink() and link_lock_path(link).read_text().split()[1] == pty
    again = _emulate(link, "--duration-s", "0.3")
    assert again.returncode == 0, again.stderr
    assert again.stdout.startswith(f"emulating on {link} -> /dev/pts/")
    assert not os.path.lexists(link) and not os.path.lexists(link_lock_path(link))
