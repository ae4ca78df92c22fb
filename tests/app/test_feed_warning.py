"""Export at a feed beyond the calibrated range: warning feed_outside_model, the cap stated."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from ctdrill.app.cli import main
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"


def _export(out: Path, *extra: str) -> dict:  # type: ignore[type-arg]
    argv = ["export", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main([*argv, "--out", str(out), *extra]) == 0
    return json.loads((out / "summary.json").read_text())  # type: ignore[no-any-return]


def test_feed_beyond_the_model_is_stated_once(tmp_path: Path) -> None:
    normal = _export(tmp_path / "a")
    assert "feed_outside_model" not in [w["code"] for w in normal["warnings"]]
    fast = _export(tmp_path / "b", "--feed-mm-s", "200")
    notes = [w["message"] for w in fast["warnings"] if w["code"] == "feed_outside_model"]
    assert len(notes) == 1
    assert "0.1..0.6 mm/s" in notes[0] and "capped at 50 mm/s" in notes[0]
    assert fast["feed_mm_s"] == 200.0
