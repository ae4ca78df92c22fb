"""A perfect guarded session scores 100 on a real CT's plan too: the depth is measured against
the goal (the guarded stop), whatever the case's geometry."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from bench.bench_report import real_plan
from ctdrill.app.cli import main

PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"


def test_a_perfect_guarded_session_on_a_real_ct_scores_100(
    shared_data: Path, tmp_path: Path
) -> None:
    # the first implant of the real head's arch: 22.6 mm planned, the margin's stop at 22.59
    # mm; 19 N reaches it after 7.9 s and lets go 150 ms after the wall
    out = tmp_path / "real"
    argv = ["rehearse", "--dicom", str(shared_data / PHILIPS), "--plan", str(real_plan(tmp_path))]
    argv += ["--trajectory", "1", "--out", str(out), "--duration-s", "9.5"]
    with contextlib.redirect_stdout(io.StringIO()):
        code = main([*argv, "--operator", "human:force=19,react_ms=150"])
    assert code == 0
    a = json.loads((out / "summary.json").read_text())["assessment"]
    assert a["goal_depth_mm"] < 22.6 and abs(a["depth_error_mm"]) < 1e-3 and not a["breach"]
    assert a["wall_contacts"] == 1 and a["score"] == 100.0
    # and ctdrill assess recomputes it from the trace
    assert main(["assess", str(out), "--db", str(tmp_path / "r.db"), "--trainee", "t"]) == 0
