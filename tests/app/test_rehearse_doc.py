"""docs/rehearse.md's numbers are what the code gives: the demo's guarded session, its score
and CLI line, a drill sequence's scores and the best score a guarded session can reach."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.cli import main
from ctdrill.app.trainee.words import assessment_line
from ctdrill.haptics.assessment import score_of
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.plan.write import save_plan
from tests.conftest import ASSETS, ROOT

DEMO = ASSETS / "demo"
HUMAN = "human:force=12,react_ms=150"


def _doc() -> str:
    """docs/rehearse.md with its line breaks as spaces (a sentence may wrap)."""
    return re.sub(r"\s+", " ", (ROOT / "docs" / "rehearse.md").read_text(encoding="utf-8"))


def _rehearse(plan: Path, out: Path) -> dict[str, Any]:
    argv = ["rehearse", "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)]
    with contextlib.redirect_stdout(io.StringIO()):
        assert main([*argv, "--operator", HUMAN, "--duration-s", "3"]) == 0
    doc: dict[str, Any] = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    return doc


@pytest.fixture(scope="module")
def guarded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return _rehearse(DEMO / "plan.json", tmp_path_factory.mktemp("doc") / "out")


def test_the_guarded_session_is_as_documented(guarded: dict[str, Any]) -> None:
    doc = _doc()
    score = guarded["assessment"]["score"]
    assert f"`{assessment_line(guarded)}`" in doc
    assert (
        f"they meet the wall at {guarded['stop_depth_mm']:.2f} mm, let go and score {score}" in doc
    )


def test_the_best_guarded_score_is_as_documented(guarded: dict[str, Any]) -> None:
    # depth error against the goal (the guarded stop), not the planned depth the guard never
    # allows: the demo's guarded session, a perfect one, scores the top
    a = guarded["assessment"]
    assert a["goal_depth_mm"] == pytest.approx(guarded["stop_depth_mm"], abs=1e-3)
    assert a["depth_error_mm"] == pytest.approx(0.0, abs=1e-3) and a["attempted"] is True
    assert a["score"] == score_of(a) == 100.0
    assert "so a perfect guarded session scores 100 on every case" in _doc()


def test_the_sequence_is_as_documented(tmp_path: Path) -> None:
    drills = (DrillSpec(diameter_mm=2.0, tip_length_mm=0.6), DrillSpec(diameter_mm=2.8))
    save_plan(load_plan(DEMO / "plan.json").with_drills(drills), tmp_path / "plan.json")
    top = _rehearse(tmp_path / "plan.json", tmp_path / "out")
    one, two = (d["score"] for d in top["drills"])
    sequence = top["assessment"]["score"]
    assert f"the drills score {one} and {two}, the sequence {sequence}" in _doc()
