"""``ctdrill gui`` refuses before Qt starts: no display, an unreachable X server, a plan that
cannot be read (exit 2, one ``error:`` line, never Qt's abort)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ctdrill.app.commands.gui import display_problem, x11_reachable

ROOT = Path(__file__).resolve().parents[3]
DEMO_PLAN = ROOT / "assets" / "demo" / "plan.json"


def run_gui(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    base = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    base.pop("QT_QPA_PLATFORM", None)
    return subprocess.run(
        [sys.executable, "-m", "ctdrill.app.cli", "gui", *args],
        capture_output=True,
        text=True,
        env={**base, **env},
        timeout=60,
        check=False,
    )


def one_error_line(proc: subprocess.CompletedProcess[str]) -> str:
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    return proc.stderr


@pytest.mark.parametrize(
    ("env", "says"),
    [
        ({}, "neither DISPLAY nor WAYLAND_DISPLAY"),
        ({"DISPLAY": ":987"}, "cannot connect to the X display DISPLAY=:987"),
        ({"QT_QPA_PLATFORM": "offscreen", "DISPLAY": ":987"}, "offscreen draws no window"),
        ({"QT_QPA_PLATFORM": "wayland"}, "WAYLAND_DISPLAY is not set"),
    ],
)
def test_no_display_is_one_error_line_naming_xvfb_run(env: dict[str, str], says: str) -> None:
    err = one_error_line(run_gui([], env))
    assert says in err and "xvfb-run" in err and "desktop session" in err


def test_display_rules_without_qt() -> None:
    assert display_problem({}, platform="darwin") is None  # macOS always has a window server
    assert display_problem({"WAYLAND_DISPLAY": "wayland-0"}, platform="linux") is None
    assert display_problem({"QT_QPA_PLATFORM": "xcb"}, platform="linux") is not None
    assert display_problem({"QT_QPA_PLATFORM": "minimal:x=1"}, platform="linux") is not None
    assert not x11_reachable(":987")
    assert x11_reachable("not-a-display-name")  # left to Qt


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ('{"format": ', "not valid JSON"),
        (DEMO_PLAN.read_text().replace('"margin_mm"', '"margn_mm"'), "margn_mm"),
    ],
)
def test_a_plan_that_cannot_be_read_is_exit_2_before_any_window(
    tmp_path: Path, text: str, says: str
) -> None:
    bad = tmp_path / "plan.json"
    bad.write_text(text)
    # No display either: the plan is refused first, so the window never opens with a default.
    err = one_error_line(run_gui(["--plan", str(bad)], {}))
    assert "plan.json" in err and says in err
