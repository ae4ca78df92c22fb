"""The force path on every synthetic corpus series that loads: a force map or a clean refusal.

The plan drills 5 mm straight down the middle of the 5 x 7 x 7 mm base series (a 2 mm drill
fits inside). Whatever the series' oddity (tilt, gaps, padding, duplicates, not HU, lossy, a
single slice), ``plan_path`` must give finite profiles with the stop inside the plan or refuse
with an input error; ``ctdrill export`` (on a sample) writes its four files with finite numbers
or exits 2 with one ``error:`` line; exit 1 (a traceback) is a bug.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from tests.robustness.corpus_base import (
    COL_SPACING_MM,
    COLS,
    ORIGIN_LPS,
    ROW_SPACING_MM,
    ROWS,
    SLICE_SPACING_MM,
    SLICES,
)
from tests.robustness.make_corpus import SYNTHETIC, Case
from tests.robustness.outcomes import error_line_problems, run_cli_in_process
from tests.robustness.test_found_bugs import BUG_CASES

CENTRE = (
    ORIGIN_LPS[0] + COL_SPACING_MM * (COLS - 1) / 2,
    ORIGIN_LPS[1] + ROW_SPACING_MM * (ROWS - 1) / 2,
)
TOP_MM = ORIGIN_LPS[2] + SLICE_SPACING_MM * (SLICES - 1)
PLAN = {
    "format": "ctdrill-plan/1",
    "coordinate_system": "LPS",
    "entry_mm": [CENTRE[0], CENTRE[1], TOP_MM - 1.0],  # the lip's back edge stays inside
    "target_mm": [CENTRE[0], CENTRE[1], TOP_MM - 6.0],
    "drill": {"diameter_mm": 2.0, "tip_length_mm": 0.6, "blades": 2, "rpm": 900},
    "feed_mm_s": 0.4,
    "calibration": "bone-illustrative",
    "margin_mm": 2.0,
    "landmarks": [],
}
#: Plain series on which the export must succeed (the plan fits inside them).
MUST_EXPORT = {"clean", "implicit_vr", "rle_lossless", "padding", "junk_beside_series", "localizer"}
LOADABLE = [
    name
    for name, (builder, _, isolate) in SYNTHETIC.items()
    if not isolate and name not in BUG_CASES
]


@pytest.fixture(scope="module")
def plan_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("plan") / "plan.json"
    path.write_text(json.dumps(PLAN))
    return path


@pytest.mark.parametrize("name", LOADABLE)
def test_force_path_gives_force_map_or_clean_refusal(
    name: str, cases: dict[str, Case], plan_path: Path
) -> None:
    """The headless path the export, rehearsal and GUI share
    (``ctdrill.engine.path.plan_path``)."""
    from ctdrill.app.errors import AppInputError
    from ctdrill.engine.path import plan_path as force_path
    from ctdrill.imaging import ImagingInputError, load_series
    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.model import load_calibration

    case = cases[name]
    try:
        volume = load_series(case.path)
    except ImagingInputError:
        return  # refused at load: test_corpus.py checks that outcome
    plan = load_plan(plan_path)
    try:
        result = force_path(volume, plan, load_calibration(plan.calibration))
    except (AppInputError, ImagingInputError) as exc:
        assert name not in MUST_EXPORT, f"{name}: {exc}"
        assert str(exc).strip() and "\n" not in str(exc).strip()
        return
    assert 0.0 <= result.stop_depth_mm <= plan.planned_depth_mm + 1e-9
    for arr in (result.profile.s0_n, result.profile.sk_n, result.profile.s_t, result.lip.hu):
        assert np.isfinite(arr).all()


@pytest.mark.parametrize("name", ["clean", "padding", "slice_gap"])
def test_export_cli_writes_finite_files_or_refuses_in_one_line(
    name: str, cases: dict[str, Case], plan_path: Path, tmp_path: Path
) -> None:
    case = cases[name]
    out = tmp_path / "out"
    args = ["export", "--dicom", str(case.path), "--plan", str(plan_path), "--out", str(out)]
    run = run_cli_in_process(args)
    if name in MUST_EXPORT:
        assert run.code == 0, f"{name}: {run.stderr}"
    if run.code == 2:
        assert not error_line_problems(run), error_line_problems(run)
        return
    assert run.code == 0, f"{name}: exit {run.code}: {run.stderr[-1500:]}"
    assert {"force.csv", "profile.csv", "summary.json", "force.png"} <= {
        p.name for p in out.iterdir()
    }
    summary = json.loads((out / "summary.json").read_text())
    assert 0.0 <= summary["stop_depth_mm"] <= summary["planned_depth_mm"] + 1e-9
    for table in ("force.csv", "profile.csv"):
        with (out / table).open() as fh:
            for row in csv.DictReader(fh):
                for key in ("depth_mm", "hu", "s_t", "force_n", "s0_n"):
                    if key in row and row[key] != "":
                        assert math.isfinite(float(row[key])), (table, key, row)
