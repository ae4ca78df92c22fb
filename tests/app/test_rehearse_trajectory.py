"""``ctdrill rehearse --trajectory``: one trajectory of a plan file holding several."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.write import write_plans
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"


def _two(tmp_path: Path) -> Path:
    """The demo trajectory ("site") and a shallower one 6 mm along the arch ("near")."""
    demo = load_plan(DEMO / "plan.json")
    shift = np.array([0.0, 6.0, 0.0])
    near = replace(
        demo,
        name="near",
        entry_lps=demo.entry_lps + shift,
        target_lps=demo.entry_lps + shift + np.array([0.0, 0.0, -8.0]),
        implant=None,
    )
    path = tmp_path / "two.json"
    write_plans([replace(demo, name="site"), near], path)
    return path


def _argv(plan: Path, out: Path, *extra: str) -> list[str]:
    return [
        "rehearse", "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out),
        "--operator", "push:40", "--duration-s", "1", *extra,
    ]  # fmt: skip


def test_rehearse_picks_a_trajectory_by_name_or_number(tmp_path: Path) -> None:
    plan = _two(tmp_path)
    for pick in ("near", "2"):
        out = tmp_path / f"out-{pick}"
        assert main(_argv(plan, out, "--trajectory", pick)) == 0
        s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        assert s["planned_depth_mm"] == pytest.approx(8.0, abs=1e-12)
        assert s["stop_reason"] == "planned_depth"


def test_rehearse_without_a_pick_or_a_wrong_one_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan = _two(tmp_path)
    assert main(_argv(plan, tmp_path / "a")) == 2
    err = capsys.readouterr().err
    assert err == (
        "error: the plan files hold 2 trajectories (1: 'site', 2: 'near'); pick one with "
        "--trajectory NAME (or its number)\n"
    )
    assert main(_argv(plan, tmp_path / "b", "--trajectory", "3")) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --trajectory '3': the plan files hold no trajectory")
    assert err.count("\n") == 1
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
