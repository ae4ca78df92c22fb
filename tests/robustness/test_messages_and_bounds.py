"""Messages name their cause, and work is bounded (issue 29).

- a grey-to-HU map that sends the series beyond any CT number is refused naming the option,
  the map and the range (not "lip_hu contains NaN" from deep inside the sampler);
- numbers in messages are short (:func:`ctdrill.numtext.number_text`): a feed of 1e-300
  gives "1.08e+304 samples", not 300 digits, and names the plan's ``feed_mm_s``;
- trajectories whose output folders collide are both named;
- a refusal is the one line on stderr (progress goes to stdout);
- a plan holds at most ``MAX_TRAJECTORIES`` trajectories, in every form it is read or written;
  the report draws pages for at most ``MAX_DRAWN_TRAJECTORIES`` and a cross-section its
  nearest neighbours only.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, replace
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ctdrill.app.report.entries import MAX_DRAWN_TRAJECTORIES, drawn_entries, undrawn_note
from ctdrill.app.report.views import MAX_NEIGHBOURS, NEIGHBOUR_MM, neighbours
from ctdrill.imaging.plan.load import load_plan, load_plan_set
from ctdrill.imaging.plan.types import MAX_TRAJECTORIES, Plan, PlanInputError
from ctdrill.imaging.plan.write import plan_to_markups, write_plans
from ctdrill.numtext import number_text
from tests.conftest import ASSETS
from tests.robustness.outcomes import CliRun, error_line_problems, run_cli_in_process

DEMO = ASSETS / "demo"


def _export(plan: Path, out: Path, *extra: str) -> CliRun:
    fast = ["--rate-hz", "100", "--no-plot"]
    ct = ["--dicom", str(DEMO / "ct")]
    return run_cli_in_process(
        ["export", *ct, "--plan", str(plan), "--out", str(out), *fast, *extra]
    )


# -- the grey map's range ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "option",
    [
        ["--grey-to-hu", "1e300,0"],  # float32 overflow: the case
        ["--grey-to-hu", "1e6,0"],  # finite, beyond any material
        ["--grey-to-hu=-1e6,0"],
        ["--grey-to-hu", "1,1e9"],
        ["--grey-to-hu", "1e300,0,1,1"],  # with standard errors
        ["--grey-ref", "15,-9,-55,2=-1000", "--grey-ref", "37,10.6,-40.2,0.8=1e12"],
    ],
    ids=["1e300", "1e6", "-1e6", "intercept-1e9", "1e300-with-se", "regions-1e12"],
)
def test_a_grey_map_beyond_any_ct_number_is_refused_naming_it(
    tmp_path: Path, option: list[str]
) -> None:
    run = _export(DEMO / "plan.json", tmp_path / "out", *option)
    assert not error_line_problems(run), run
    message = run.stderr
    assert message.startswith(f"error: {option[0].split('=')[0]}") and "HU = " in message
    assert "beyond the +/-100000 HU any material has" in message
    assert "nan" not in message.lower()
    assert not (tmp_path / "out").exists()


def test_a_grey_map_inside_the_range_on_an_hu_series_warns(tmp_path: Path) -> None:
    run = _export(DEMO / "plan.json", tmp_path / "out", "--grey-to-hu", "1.1,-20")
    assert run.code == 0, run.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text(encoding="utf-8"))
    warned = [w for w in summary["warnings"] if w["code"] == "grey_map_on_hu"]
    assert len(warned) == 1 and "already in HU" in warned[0]["message"]
    assert "grey_map_on_hu" in run.stdout


# -- numbers in messages ------------------------------------------------------------------------


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_number_text_is_short_and_close(value: float) -> None:
    text = number_text(value)
    assert len(text) <= 13
    assert math.isclose(float(text), value, rel_tol=1e-5, abs_tol=0.0) or value == 0.0


@given(st.integers(min_value=-(10**600), max_value=10**600))
def test_number_text_of_any_integer_is_short(value: int) -> None:
    text = number_text(value)
    assert len(text) <= 16
    if abs(value) < 10**15:
        assert text == str(value)
    else:
        exact = Decimal(value)
        assert abs(Decimal(text) - exact) <= abs(exact) * Decimal("1e-5")


@pytest.mark.parametrize("feed", [1e-300, 5e-324, 1e-100])
def test_a_tiny_feed_is_refused_naming_the_plans_feed_in_short_numbers(
    tmp_path: Path, feed: float
) -> None:
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc["feed_mm_s"] = feed
    plan = tmp_path / "slow.json"
    plan.write_text(json.dumps(doc), encoding="utf-8")
    run = _export(plan, tmp_path / "out")
    assert not error_line_problems(run), run
    assert run.stderr.startswith("error: plan 'slow': feed_mm_s ")
    assert len(run.stderr) < 300 and not re.search(r"\d{16}", run.stderr), run.stderr
    run = _export(DEMO / "plan.json", tmp_path / "out", "--feed-mm-s", repr(feed))
    assert not error_line_problems(run), run
    assert run.stderr.startswith("error: --feed-mm-s ") and not re.search(r"\d{16}", run.stderr)


# -- names and the single error line ----------------------------------------------------------


def _several(tmp_path: Path, names: list[str]) -> Path:
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    shared = {k: doc[k] for k in ("format", "coordinate_system", "landmarks")}
    shared["trajectories"] = [
        {"name": n, "entry_mm": [32.0 + i, 10.0, -29.0], "target_mm": [32.0 + i, 10.0, -41.0]}
        for i, n in enumerate(names)
    ]
    path = tmp_path / "case.json"
    path.write_text(json.dumps(shared), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    "names", [[".", ".."], ["a/b", "a_b"], ["x y", "x_y"], ["left", "_", "__"]], ids=str
)
def test_colliding_output_folders_name_both_trajectories_in_one_line(
    tmp_path: Path, names: list[str]
) -> None:
    plan = _several(tmp_path, names)
    for command in ("export", "report"):
        out = tmp_path / ("out" if command == "export" else "r.pdf")
        run = run_cli_in_process(
            [command, "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)]
        )
        assert not error_line_problems(run), run  # the progress went to stdout
        assert f"{command} [" in run.stdout
        quoted = re.findall(r"'((?:[^'\\]|\\.)*)' \(case\.json\)", run.stderr)
        assert len(set(quoted)) == 2 and set(quoted) <= set(names), run.stderr
        assert not out.exists()


# -- trajectory caps --------------------------------------------------------------------------


def _plans(n: int) -> tuple[Plan, ...]:
    demo = load_plan(DEMO / "plan.json")
    return tuple(
        replace(
            demo,
            name=f"t{i}",
            entry_lps=demo.entry_lps + np.array([0.01 * i, 0.0, 0.0]),
            target_lps=demo.target_lps + np.array([0.01 * i, 0.0, 0.0]),
            implant=None,
        )
        for i in range(n)
    )


def test_a_plan_of_the_most_trajectories_reads_and_writes(tmp_path: Path) -> None:
    plans = _plans(MAX_TRAJECTORIES)
    for name in ("most.json", "most.mrk.json"):
        write_plans(plans, tmp_path / name)
        assert len(load_plan_set([tmp_path / name])) == MAX_TRAJECTORIES


def test_one_trajectory_more_is_refused_in_every_form(tmp_path: Path) -> None:
    n = MAX_TRAJECTORIES + 1
    plans = _plans(n)
    with pytest.raises(PlanInputError, match=f"{n} trajectories to write, more than the"):
        write_plans(plans, tmp_path / "x.json")
    assert not (tmp_path / "x.json").exists()
    # a ctdrill-plan/1 file and a markups file written by hand
    write_plans(plans[:MAX_TRAJECTORIES], tmp_path / "most.json")
    doc = json.loads((tmp_path / "most.json").read_text(encoding="utf-8"))
    doc["trajectories"].append({**doc["trajectories"][0], "name": "extra"})
    (tmp_path / "more.json").write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(PlanInputError, match=f"more.json: trajectories lists {n} trajectories"):
        load_plan_set([tmp_path / "more.json"])
    markups = plan_to_markups(plans[:MAX_TRAJECTORIES])
    markups["markups"].insert(0, markups["markups"][0] | {"name": "extra"})
    (tmp_path / "more.mrk.json").write_text(json.dumps(markups), encoding="utf-8")
    with pytest.raises(PlanInputError, match=f"hold {n} Line markups"):
        load_plan_set([tmp_path / "more.mrk.json"])
    # a folder of one-trajectory files: refused at the file past the limit
    folder = tmp_path / "folder"
    folder.mkdir()
    for p in plans:
        write_plans((p,), folder / f"{p.name:>04}.json")
    with pytest.raises(PlanInputError, match=f"more than the {MAX_TRAJECTORIES} trajectories"):
        load_plan_set([folder])
    run = _export(tmp_path / "more.json", tmp_path / "out", "--per-trajectory")
    assert not error_line_problems(run) and "more.json" in run.stderr


@dataclass(frozen=True)
class _Result:
    plan: Plan


@dataclass(frozen=True)
class _Entry:
    result: _Result


def _entries(n: int, spacing_mm: float) -> list[_Entry]:
    demo = load_plan(DEMO / "plan.json")
    shift = np.array([spacing_mm, 0.0, 0.0])
    return [
        _Entry(
            _Result(
                replace(
                    demo,
                    name=f"t{i}",
                    entry_lps=demo.entry_lps + i * shift,
                    target_lps=demo.target_lps + i * shift,
                )
            )
        )
        for i in range(n)
    ]


def test_the_report_draws_pages_for_the_first_trajectories_and_names_the_rest() -> None:
    few = _entries(MAX_DRAWN_TRAJECTORIES, 5.0)
    assert drawn_entries(few) == few and undrawn_note(few) is None  # type: ignore[arg-type]
    many = _entries(MAX_TRAJECTORIES, 5.0)
    drawn = drawn_entries(many)  # type: ignore[arg-type]
    assert drawn == many[:MAX_DRAWN_TRAJECTORIES]
    note = undrawn_note(many)  # type: ignore[arg-type]
    assert note is not None
    assert f"first {MAX_DRAWN_TRAJECTORIES} of {MAX_TRAJECTORIES} trajectories" in note
    assert f"t{MAX_DRAWN_TRAJECTORIES}," in note and "more" in note


def test_a_cross_section_draws_its_nearest_neighbours_only() -> None:
    close = _entries(40, 1.0)  # axes 1 mm apart: every one within reach of the first ones
    near = neighbours(close[20], close)  # type: ignore[arg-type]
    assert len(near) == MAX_NEIGHBOURS + 1 and close[20] in near
    assert {e.result.plan.name for e in near} == {f"t{i}" for i in range(16, 25)}
    apart = _entries(4, NEIGHBOUR_MM + 1.0)  # beyond reach: alone on its page
    assert neighbours(apart[1], apart) == [apart[1]]  # type: ignore[arg-type]
