"""A setting is given once: twice in one description, or at two levels with different values,
is one ``error:`` line naming both (never last-wins, never the point silently winning).

Other instances than the one first reported (``radius_mm=1.2 radius_mm=0.01`` on a canal
stopped the demo at 11.99 mm instead of 10.80): a Line's margin and feed, a Fiducial's margin,
the same value twice, markup description against attributes; through ``load_plan`` and
``ctdrill export``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ctdrill import api
from ctdrill.imaging.plan.settings import SettingsSyntaxError, parse_settings
from ctdrill.imaging.plan.types import PlanInputError
from tests.conftest import ASSETS
from tests.imaging.slicer_files import slicer_control_point, slicer_document, slicer_markup
from tests.robustness.outcomes import error_line_problems, run_cli_in_process

DEMO = json.loads((ASSETS / "demo" / "plan.json").read_text())


def _case(tmp_path: Path, line_desc: str, canal_desc: str, canal_markup: dict[str, object]) -> Path:
    line = slicer_markup(
        "Line",
        [
            slicer_control_point(0, DEMO["entry_mm"], description=line_desc),
            slicer_control_point(1, DEMO["target_mm"]),
        ],
    )
    pts = DEMO["landmarks"][0]["points_mm"]
    canal = slicer_markup(
        "Curve",
        [
            slicer_control_point(i, p, description=canal_desc if i == 0 else "")
            for i, p in enumerate(pts)
        ],
    )
    canal.update(canal_markup)
    path = tmp_path / "case.mrk.json"
    doc = slicer_document(line)
    doc["markups"].append(canal)
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    "text",
    [
        "margin_mm=2 margin_mm=0.5",
        "margin_mm=2 margin_mm=2",  # the same value twice: still not knowingly written
        'name="IAN" radius_mm=1.2 name="canal"',
        "feed_mm_s=0.4, feed_mm_s=4;",
    ],
)
def test_a_key_twice_in_one_description_is_refused(text: str) -> None:
    with pytest.raises(SettingsSyntaxError, match=r"is given twice"):
        parse_settings(text)


NAMED = 'name="IAN canal"'


@pytest.mark.parametrize(
    ("line_desc", "canal_desc", "canal_markup", "pattern"),
    [
        ("", f"{NAMED} radius_mm=1.2 radius_mm=0.05", {}, r"radius_mm is given twice"),
        ("margin_mm=2 margin_mm=0", NAMED, {}, r"margin_mm is given twice"),
        (
            "",
            f"{NAMED} radius_mm=0.3",
            {"description": "radius_mm=1.2"},
            r"controlPoints\[0\]\.description: setting radius_mm is 0\.3 here and 1\.2 in "
            r"markups\[1\]\.description",
        ),
        (
            "",
            f"{NAMED} margin_mm=0.5",
            {"attributes": {"margin_mm": 3.0}},
            r"markups\[1\]\.attributes: setting margin_mm is 3\.0 here and 0\.5",
        ),
        (
            "",
            f"{NAMED} radius_mm=1.2",
            {"description": 'name="other canal"'},
            r"setting name is 'IAN canal' here and 'other canal'",
        ),
    ],
)
def test_settings_given_twice_are_one_error_line(
    tmp_path: Path,
    line_desc: str,
    canal_desc: str,
    canal_markup: dict[str, object],
    pattern: str,
) -> None:
    path = _case(tmp_path, line_desc, canal_desc, canal_markup)
    with pytest.raises(PlanInputError, match=pattern):
        api.load_plan(path)
    run = run_cli_in_process(
        [
            "export",
            "--dicom",
            str(ASSETS / "demo" / "ct"),
            "--plan",
            str(path),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert not error_line_problems(run), error_line_problems(run)
    assert "case.mrk.json" in run.stderr and not (tmp_path / "out").exists()


def test_the_same_value_at_two_levels_is_accepted(tmp_path: Path) -> None:
    path = _case(
        tmp_path,
        "",
        f"{NAMED} radius_mm=1.2",
        {"description": "radius_mm=1.20", "attributes": {"radius_mm": 1.2}},
    )
    (canal,) = api.load_plan(path).landmarks
    assert canal.name == "IAN canal" and canal.radius_mm == 1.2


def test_a_point_landmark_setting_twice_is_refused(tmp_path: Path) -> None:
    line = slicer_markup(
        "Line",
        [
            slicer_control_point(0, DEMO["entry_mm"]),
            slicer_control_point(1, DEMO["target_mm"]),
        ],
    )
    points = slicer_markup(
        "Fiducial",
        [slicer_control_point(0, [30.0, 10.0, -45.0], description="margin_mm=3 margin_mm=1")],
    )
    doc = slicer_document(line)
    doc["markups"].append(points)
    path = tmp_path / "p.mrk.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(PlanInputError, match=r"margin_mm is given twice \(margin_mm=3, then"):
        api.load_plan(path)
