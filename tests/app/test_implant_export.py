"""Implant warnings in ``ctdrill export``: the demo's implant against its stop, two implants
of one plan file too close, every code + message once."""

from __future__ import annotations

import contextlib
import csv
import io
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from ctdrill.app.cli import main
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.write import write_plans
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def test_demo_implant_is_left_short_by_the_margin_stop(tmp_path: Path) -> None:
    out = tmp_path / "out"
    argv = ["export", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    code, _, err = _run([*argv, "--out", str(out), "--no-plot", "--rate-hz", "100"])
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    beyond = [w for w in s["warnings"] if w["code"] == "implant_beyond_stop"]
    assert len(beyond) == 1
    # The stop (10.8 mm, the margin) is shallower than the implant's apex at the target (12 mm);
    # the drill is planned to the apex plus its tip (0.6 mm).
    assert s["stop_reason"] == "margin" and s["stop_depth_mm"] < s["planned_depth_mm"] == 12.6
    assert "needs an osteotomy 12.00 mm deep" in beyond[0]["message"]
    assert f"stops at {s['stop_depth_mm']:.2f} mm (margin)" in beyond[0]["message"]
    assert not any(w["code"] == "implant_above_entry" for w in s["warnings"])
    codes = [(w["code"], w["message"]) for w in s["warnings"]]
    assert len(codes) == len(set(codes))
    implant = s["implant"]
    assert implant["name"] == "tapered 4.1 x 11.5" and implant["seated"] is False
    assert implant["apex_lps"] == s["target_lps"] and implant["axis_lps"] == [0.0, 0.0, -1.0]
    # The platform 11.5 mm back from the target along the axis: 0.5 mm under the entry.
    assert implant["platform_lps"] == [s["entry_lps"][0], s["entry_lps"][1], -29.5]
    assert (implant["platform_depth_mm"], implant["apex_depth_mm"]) == (0.5, 12.0)


def test_two_implants_under_3_mm_apart_warn_on_both_rows(tmp_path: Path) -> None:
    demo = load_plan(DEMO / "plan.json")
    assert demo.implant is not None
    # Parallel, 6 mm apart along the arch: 6 - 4.1 = 1.9 mm between the platforms.
    shift = np.array([0.0, 6.0, 0.0])
    near = replace(
        demo, name="near", entry_lps=demo.entry_lps + shift, target_lps=demo.target_lps + shift
    )
    far_shift = np.array([0.0, -9.0, 0.0])
    far = replace(
        demo,
        name="far",
        entry_lps=demo.entry_lps + far_shift,
        target_lps=demo.target_lps + far_shift,
    )
    plan = tmp_path / "three.json"
    write_plans([replace(demo, name="site"), near, far], plan)
    out = tmp_path / "out"
    argv = ["export", "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)]
    code, _, err = _run([*argv, "--no-plot", "--per-trajectory", "--rate-hz", "100"])
    assert code == 0, err
    with (out / "trajectories.csv").open(encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 3
    by_folder = {}
    for row in rows:
        s = json.loads((out / row["folder"] / "summary.json").read_text(encoding="utf-8"))
        close = [w["message"] for w in s["warnings"] if w["code"] == "implants_too_close"]
        by_folder[row["folder"]] = close
        assert ("implants_too_close" in row["warnings"].split(";")) == bool(close)
    warned = {k: v for k, v in by_folder.items() if v}
    assert len(warned) == 2 and all(len(v) == 1 for v in warned.values())
    (message,) = {v[0] for v in warned.values()}
    assert message.startswith("implants of 'site' and 'near' are 1.90 mm apart")


def test_the_window_reports_implants_too_close_as_export_does() -> None:
    from ctdrill.app.gui.results import compute_path_view
    from ctdrill.imaging import load_series

    demo = replace(load_plan(DEMO / "plan.json"), name="site")
    shift = np.array([0.0, 6.0, 0.0])  # 1.9 mm between the 4.1 mm platforms
    near = replace(
        demo, name="near", entry_lps=demo.entry_lps + shift, target_lps=demo.target_lps + shift
    )
    volume = load_series(DEMO / "ct")
    alone = compute_path_view(volume, demo)
    in_set = compute_path_view(volume, demo, plan_set=(demo, near))
    codes = [w.code for w in in_set.result.warnings]
    assert "implants_too_close" not in [w.code for w in alone.result.warnings]
    assert codes.count("implants_too_close") == 1
    # The view belongs to the document's own plan object (the window matches results by it).
    assert in_set.plan is demo
    # The orange envelope is named for what it is: the device's vibration, not an uncertainty.
    assert in_set.curves.band_note.startswith("orange: vibration range; no uncertainty band")
