"""The score does not depend on the session's length (docs/rehearse.md, "The score"): the same
operator on the demo, rehearsed for two durations both past the stop, scores the same, a hand
that never lets go of the wall included."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.cli import main
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
#: What :func:`ctdrill.haptics.score.score_of` reads (``mean_hand_force_n``, ``feed_cv`` and the
#: wall's force are reported, not scored).
SCORED = (
    "depth_error_mm",
    "overshoot_mm",
    "breach",
    "canal_entered",
    "attempted",
    "peak_hand_force_n",
    "hand_force_cv",
    "reaction_ms",
    "display_lagged",
    "plunge_mm",
    "wall_contacts",
    "wall_press_s",
    "wall_overrun_mm",
    "time_in_margin_s",
    "score",
)


def _assessment(out: Path, operator: str, duration_s: float, *, exam: bool) -> dict[str, Any]:
    argv = ["rehearse", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    argv += ["--out", str(out), "--operator", operator, "--duration-s", str(duration_s)]
    with contextlib.redirect_stdout(io.StringIO()):
        assert main([*argv, "--exam"] if exam else argv) == 0
    doc: dict[str, Any] = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assessment: dict[str, Any] = doc["assessment"]
    return assessment


@pytest.mark.parametrize(
    ("operator", "durations_s", "exam"),
    [
        ("push:12", (3.0, 5.0), False),  # meets the wall at 2.36 s and never lets go
        ("human:force=12,react_ms=800", (3.0, 5.0), False),  # lets go at 3.2 s
        # through the canal to the exam's stop (22.6 mm) by 2.3 s, never letting go: the
        # whole reaction term and a saturated press, however long it goes on
        ("push:20", (2.5, 4.0), True),
    ],
)
def test_the_same_operator_scores_the_same_at_two_durations(
    tmp_path: Path, operator: str, durations_s: tuple[float, float], exam: bool
) -> None:
    short, long = (_assessment(tmp_path / f"d{d}", operator, d, exam=exam) for d in durations_s)
    assert short["wall_contacts"] == long["wall_contacts"] == 1
    assert short["score"] == long["score"] < 100.0  # pressing on the wall costs points
    assert {f: short[f] for f in SCORED} == {f: long[f] for f in SCORED}
