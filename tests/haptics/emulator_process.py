"""``ctdrill emulate`` in a subprocess on a pseudo-terminal, for the serial-path tests."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


def demo_rehearsal(out: Path, operator: str, duration_s: str, *extra: str) -> list[str]:
    """``ctdrill rehearse`` arguments for the demo phantom and plan into ``out``."""
    return [
        "rehearse",
        "--dicom",
        str(DEMO / "ct"),
        "--plan",
        str(DEMO / "plan.json"),
        "--out",
        str(out),
        "--operator",
        operator,
        "--duration-s",
        duration_s,
        *extra,
    ]


def spawn_emulator(link: Path) -> subprocess.Popen[str]:
    """Start ``ctdrill emulate --pty-link link`` and return its process once it serves."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "ctdrill.app.cli", "emulate", "--pty-link", str(link)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line.startswith(f"emulating on {link} -> /dev/pts/"), line
    return proc


@contextmanager
def emulator_process(link: Path) -> Iterator[subprocess.Popen[str]]:
    """Run the device emulator linked at ``link`` (a serial port stand-in); yield its process.

    On exit it is stopped with SIGTERM (after SIGCONT, should a test have frozen it) and must
    end cleanly: exit code 0, its closing report on stderr, and the link removed.
    """
    proc = spawn_emulator(link)
    try:
        yield proc
    finally:
        proc.send_signal(signal.SIGCONT)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "emulator stopped" in err
    assert not link.exists() and not link.is_symlink()  # the link is cleaned up


@contextmanager
def emulator_on_pty(link: Path) -> Iterator[Path]:
    """:func:`emulator_process`, yielding the link."""
    with emulator_process(link):
        yield link
