"""JSON input refuses a key given twice in one object, naming the key and the file.

Python's ``json`` keeps the last value silently: a plan with ``margin_mm`` 2.0 then 0.0 ran
with margin 0. Here every object of every kind of JSON a user hands ctdrill (plans, Slicer
markups, calibration sets, implant libraries, a Line's ``drills`` setting), at every depth,
is given a duplicate key, and each reader refuses it through the Python API and the CLI.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from ctdrill.imaging.plan.implants import (
    DEFAULT_LIBRARY,
    ImplantInputError,
    load_implant_library,
)
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import PlanInputError
from ctdrill.imaging.plan.write import plan_to_markups
from ctdrill.model.calibration import CalibrationError, load_calibration
from ctdrill.safeio import loads_json
from tests.conftest import ASSETS
from tests.robustness.outcomes import error_line_problems, run_cli_in_process

DEMO = ASSETS / "demo"
Path_ = tuple[Any, ...]


def _objects(doc: Any, path: Path_ = ()) -> Iterator[Path_]:
    """The path of every JSON object in ``doc`` (depth first, the document's own first)."""
    if isinstance(doc, dict):
        yield path
        for key, value in doc.items():
            yield from _objects(value, (*path, key))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            yield from _objects(value, (*path, i))


def _get(doc: Any, path: Path_) -> Any:
    for step in path:
        doc = doc[step]
    return doc


def with_duplicate(doc: Any, path: Path_) -> tuple[str, str]:
    """JSON text of ``doc`` where the object at ``path`` gives its first key a second time
    (another value), and that key."""
    target = _get(doc, path)
    key = next(iter(target))
    sentinel = "\x00duplicate\x00"
    tree = copy.deepcopy(doc)
    if path:
        _get(tree, path[:-1])[path[-1]] = sentinel
    else:
        tree = sentinel
    inner = json.dumps(target)[:-1] + f", {json.dumps(key)}: {json.dumps([0])}}}"
    return json.dumps(tree).replace(json.dumps(sentinel), inner), key


def _cases(doc: Any, limit: int = 40) -> list[Path_]:
    """Every object's path, thinned to ``limit`` spread over the document."""
    paths = list(_objects(doc))
    step = max(1, len(paths) // limit)
    return paths[::step]


def _plan_doc() -> Any:
    return json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))


def _markups_doc() -> Any:
    return plan_to_markups(load_plan(DEMO / "plan.json"))


def _calibration_doc() -> Any:
    return json.loads((ASSETS / "calibration" / "bone-literature.json").read_text("utf-8"))


def _library_doc() -> Any:
    doc = json.loads(Path(DEFAULT_LIBRARY).read_text(encoding="utf-8"))
    doc["implants"] = doc["implants"][:3]
    return doc


READERS: dict[str, tuple[Callable[[], Any], str, Callable[[Path], object], type[Exception]]] = {
    "plan": (_plan_doc, "plan.json", load_plan, PlanInputError),
    "markups": (_markups_doc, "plan.mrk.json", load_plan, PlanInputError),
    "calibration": (_calibration_doc, "cal.json", load_calibration, CalibrationError),
    "implants": (_library_doc, "mine.json", load_implant_library, ImplantInputError),
}


@pytest.mark.parametrize("kind", sorted(READERS))
def test_every_reader_refuses_a_duplicate_key_in_any_object(tmp_path: Path, kind: str) -> None:
    make, name, read, error = READERS[kind]
    doc = make()
    path = tmp_path / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    read(path)  # the document itself is good
    paths = _cases(doc)
    assert len(paths) >= 2  # the top level and nested objects
    for where in paths:
        text, key = with_duplicate(doc, where)
        path.write_text(text, encoding="utf-8")
        with pytest.raises(error) as info:
            read(path)
        message = str(info.value)
        assert f"gives the key {key!r} twice" in message, (where, message)
        assert name in message, message


def test_the_issue_case_margin_given_twice_is_refused_through_the_cli(tmp_path: Path) -> None:
    text = (DEMO / "plan.json").read_text(encoding="utf-8")
    assert text.count('"margin_mm": 2.0') == 1
    plan = tmp_path / "plan.json"
    plan.write_text(text.replace('"margin_mm": 2.0', '"margin_mm": 2.0, "margin_mm": 0.0'))
    out = tmp_path / "out"
    run = run_cli_in_process(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)]
    )
    assert not error_line_problems(run), run
    assert f"{plan}: the plan file gives the key 'margin_mm' twice" in run.stderr
    assert "(2.0, then 0.0)" in run.stderr
    assert not out.exists()


def test_calibration_and_implant_library_duplicates_are_refused_through_the_cli(
    tmp_path: Path,
) -> None:
    cal_text, _ = with_duplicate(_calibration_doc(), ("a0",))
    cal = tmp_path / "cal.json"
    cal.write_text(cal_text, encoding="utf-8")
    demo = ["--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    run = run_cli_in_process(
        ["export", *demo, "--out", str(tmp_path / "out"), "--calibration", str(cal)]
    )
    assert not error_line_problems(run), run
    assert "cal.json" in run.stderr and "gives the key 'b0' twice" in run.stderr
    lib_text, _ = with_duplicate(_library_doc(), ("implants", 1))
    lib = tmp_path / "mine.json"
    lib.write_text(lib_text, encoding="utf-8")
    out = str(tmp_path / "p.json")
    run = run_cli_in_process(
        ["plan", str(DEMO / "plan.json"), "--out", out, "--implants", str(lib), "--implant", "x"]
    )
    assert not error_line_problems(run), run
    assert "mine.json" in run.stderr and "gives the key 'name' twice" in run.stderr


def test_a_line_drills_setting_with_a_duplicate_key_is_refused(tmp_path: Path) -> None:
    doc = _markups_doc()
    cp = doc["markups"][0]["controlPoints"][0]
    drills = '[{"diameter_mm": 2.0, "diameter_mm": 3.5}, {"diameter_mm": 2.8}]'
    cp["description"] = f"drills={json.dumps(drills)}"
    path = tmp_path / "seq.mrk.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(PlanInputError, match="setting drills: the value gives the key "):
        load_plan(path)


def test_identical_duplicates_are_refused_too_and_unique_keys_parse() -> None:
    with pytest.raises(
        ValueError, match=r"x.json: the doc gives the key 'a' twice .*\(1, then 1\)"
    ):
        loads_json('{"a": 1, "a": 1}', where="x.json", what="doc", error=ValueError)
    long = "y" * 100
    with pytest.raises(ValueError, match=r"y\.\.\., then 2\)"):  # long values are cut
        loads_json(f'{{"a": "{long}", "a": 2}}', where="x.json", what="doc", error=ValueError)
    assert loads_json('{"a": {"a": 1}, "b": [{"a": 2}]}', where="x", what="d", error=ValueError)


def test_an_implant_drills_setting_with_a_duplicate_key_is_refused(tmp_path: Path) -> None:
    """The implant's drilling protocol in a Line's description is JSON too: a drill giving
    ``diameter_mm`` twice is refused, naming the key, never read as its last value."""
    doc = _markups_doc()
    cp = doc["markups"][0]["controlPoints"][0]
    drills = '[{"diameter_mm": 2.0, "diameter_mm": 3.5}, {"diameter_mm": 2.8}]'
    cp["description"] = (
        'implant="T" implant_diameter_mm=4.1 implant_length_mm=10 implant_apex_diameter_mm=2.9 '
        f"implant_apex=round implant_drills={json.dumps(drills)}"
    )
    path = tmp_path / "implant.mrk.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(PlanInputError, match="setting implant_drills: the value gives the key "):
        load_plan(path)
    clean = (
        '[{"diameter_mm": 2.0, "tip_length_mm": 0.6}, {"diameter_mm": 2.8, "tip_length_mm": 0.8}]'
    )
    cp["description"] = cp["description"].replace(json.dumps(drills), json.dumps(clean))
    path.write_text(json.dumps(doc), encoding="utf-8")
    plan = load_plan(path)  # the same protocol without the duplicate reads
    assert [d.diameter_mm for d in plan.drills] == [2.0, 2.8]
