"""``ctdrill rehearse`` of a drill sequence on the demo phantom: one session per drill, each
drill's table cut around the hole the drill before it actually reached."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.engine.sequence import drill_path
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.plan.write import save_plan
from ctdrill.model.profile import force_series_n

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"
DRILLS = (
    DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
    DrillSpec(diameter_mm=2.8, tip_length_mm=0.84),
)
FEED = 4.0


def _rows(path: Path) -> tuple[np.ndarray, np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    return np.array(
        [[float(r["time_s"]), float(r["drill_mm"]), float(r["force_cmd_n"])] for r in rows]
    ), np.array([r["state"] for r in rows])


@pytest.fixture(scope="module")
def rehearsed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, int, str]:
    base = tmp_path_factory.mktemp("rehearse_seq")
    plan = load_plan(DEMO / "plan.json").with_drills(DRILLS)
    save_plan(plan, base / "plan.json")
    out = base / "out"
    import contextlib
    import io

    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = main(
            [
                "rehearse",
                "--dicom",
                str(DEMO / "ct"),
                "--plan",
                str(base / "plan.json"),
                "--out",
                str(out),
                "--operator",
                f"feed:{FEED}",
                "--duration-s",
                "3.5",
            ]
        )
    return base / "plan.json", out, code, stdout.getvalue()


def test_one_session_per_drill_and_a_listing_summary(
    rehearsed: tuple[Path, Path, int, str],
) -> None:
    _, out, code, stdout = rehearsed
    assert code == 0
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert files == [
        "drill_1/session.csv",
        "drill_1/summary.json",
        "drill_2/session.csv",
        "drill_2/summary.json",
        "summary.json",
    ]
    top = json.loads((out / "summary.json").read_text())
    one, two = (json.loads((out / f"drill_{k}" / "summary.json").read_text()) for k in (1, 2))
    assert top["format"] == "ctdrill-rehearsal-sequence/1"
    assert top["complete"] is True and (top["drills_run"], top["drills_planned"]) == (2, 2)
    assert top["stop_depth_mm"] == two["stop_depth_mm"]  # the final drill's stop rules
    assert [d["diameter_mm"] for d in top["drills"]] == [2.0, 2.8]
    assert one["inner_holes"] == [] and one["drill"]["diameter_mm"] == 2.0
    # the hole drill 2 cut around is as deep as drill 1 actually reached in its session
    assert two["inner_holes"] == [
        {"diameter_mm": 2.0, "tip_length_mm": 0.6, "depth_mm": one["max_drill_mm"]}
    ]
    assert top["drills"][0]["reached_depth_mm"] == one["max_drill_mm"]
    assert stdout.splitlines()[0].startswith("drill 1/2 (2 mm): stop depth ")


def test_drill_two_feels_the_annulus_force(rehearsed: tuple[Path, Path, int, str]) -> None:
    """At a steady feed the device renders S0(x) (1 + Ke v) (+ vibration, averaged out over
    0.1 s windows): drill 2's force follows its annulus profile, some 3.5 times below what
    its full lip would give in the same bone."""
    plan_file, out, _, _ = rehearsed
    plan = load_plan(plan_file)
    volume = load_series(DEMO / "ct")
    cal = plan_calibration(plan)
    one = json.loads((out / "drill_1" / "summary.json").read_text())
    annulus = drill_path(volume, plan, 1, cal, [one["max_drill_mm"]]).profile
    full = plan_path(volume, plan.for_drill(1), cal).profile
    data, state = _rows(out / "drill_2" / "session.csv")
    t, x, f = data.T
    steady = (state == "cutting") & (x > 4.0) & (x < one["max_drill_mm"] - 1.0)
    assert steady.sum() > 500
    ratios, full_ratios = [], []
    for start in np.arange(t[steady][0], t[steady][-1] - 0.1, 0.1):
        w = steady & (t >= start) & (t < start + 0.1)
        if w.sum() < 50:
            continue
        v = (x[w][-1] - x[w][0]) / (t[w][-1] - t[w][0])
        want = force_series_n(annulus, x[w], v, np.full(w.sum(), np.nan))
        want_full = force_series_n(full, x[w], v, np.full(w.sum(), np.nan))
        ratios.append(f[w].mean() / want.mean())
        full_ratios.append(f[w].mean() / want_full.mean())
    assert len(ratios) >= 5
    assert np.median(ratios) == pytest.approx(1.0, abs=0.1)
    assert np.median(full_ratios) < 0.45


def test_gui_shows_the_final_drill_around_the_earlier_holes(
    rehearsed: tuple[Path, Path, int, str],
) -> None:
    """The window computes a sequence's final drill as the export's last folder and says
    which drill it is where it explains the auto-stop."""
    from ctdrill.app.gui.results import compute_path_view, stop_explanation
    from ctdrill.engine.sequence import plan_sequence

    plan_file = rehearsed[0]
    plan = load_plan(plan_file)
    volume = load_series(DEMO / "ct")
    view = compute_path_view(volume, plan)
    seq = plan_sequence(volume, plan, plan_calibration(plan))
    np.testing.assert_array_equal(view.result.profile.s0_n, seq.final.profile.s0_n)
    pilot_stop = seq.steps[0].stop_depth_mm
    assert stop_explanation(view.result).endswith(
        f" (drill 2, 2.8 mm, after 2 mm to {pilot_stop:.2f} mm)"
    )
    assert "drill" not in stop_explanation(seq.steps[0])


def test_a_fault_ends_the_sequence_and_says_how_far_it_got(
    rehearsed: tuple[Path, Path, int, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan_file = rehearsed[0]
    out = tmp_path / "out"
    code = main(
        [
            "rehearse",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(plan_file),
            "--out",
            str(out),
            "--operator",
            "push:20",
            "--duration-s",
            "0.6",
            "--fault",
            "link-loss@0.3",
        ]
    )
    assert code == 3
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert files == ["drill_1/session.csv", "drill_1/summary.json", "summary.json"]
    top = json.loads((out / "summary.json").read_text())
    assert top["complete"] is False and (top["drills_run"], top["drills_planned"]) == (1, 2)
    assert top["stop_depth_mm"] is None and top["stop_reason"] is None
    assert top["faults"] and all(f["drill"] == 1 for f in top["faults"])
    captured = capsys.readouterr()
    assert "1 of 2 drills run: the sequence ended early" in captured.out
    assert captured.err.strip().splitlines()[-1].startswith("error: the session ended early")
