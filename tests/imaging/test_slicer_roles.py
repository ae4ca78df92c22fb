"""Slicer roles come from explicit settings: a Curve is the dental arch only when its description
says ``arch`` (or, without a description, it is named exactly ``dental arch``); a word in a name
never demotes a canal. And every markups file ctdrill writes reads back as the same plan."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.imaging.plan.arch import ARCH_MARKUP_NAME, is_arch_curve
from ctdrill.imaging.plan.landmarks import CanalLandmark, PointLandmark
from ctdrill.imaging.plan.load import load_plan_set
from ctdrill.imaging.plan.slicer import MAX_CURVE_POINTS
from ctdrill.imaging.plan.types import Plan, PlanInputError
from ctdrill.imaging.plan.write import plan_to_markups, save_plan
from tests.conftest import ASSETS
from tests.imaging.slicer_files import slicer_control_point, slicer_document, slicer_markup
from tests.robustness.outcomes import run_cli_in_process

_LINE = slicer_markup(
    "Line", [slicer_control_point(0, [5.0, 5.0, 5.0]), slicer_control_point(1, [5.0, 5.0, 0.0])]
)
_CURVE_PTS = [[0.0, 0.0, 0.0], [10.0, 1.0, 0.0], [20.0, 0.0, 0.0]]


def _curve(description: str = "", name: str | None = None) -> dict[str, object]:
    cps = [
        slicer_control_point(i, p, description=description if i == 0 else "")
        for i, p in enumerate(_CURVE_PTS)
    ]
    mk = slicer_markup("Curve", cps)
    if name is not None:
        mk["name"] = name
    return mk


def _read(tmp_path: Path, markups: list[dict[str, object]], file: str = "case.mrk.json") -> Plan:
    path = tmp_path / file
    path.write_text(json.dumps({"markups": markups}), encoding="utf-8")
    (plan,) = load_plan_set([path])
    return plan


@pytest.mark.parametrize(
    ("description", "name"),
    [
        ("", "IAN canal below the arch"),  # the issue's case: the word in the markup's name
        ('name="IAN canal below the arch" radius_mm=1.2', None),  # in the name setting
        ('name="IAN canal below the arch" radius_mm=1.2', "IAN canal below the arch"),
        ('canal below the arch radius_mm=1.2 name="IAN"', None),  # free words, role word
        ("arch canal", "left canal"),
        ("", "Arch"),  # a name that is not exactly the documented one
        ("", "dental arch 2"),
        ("IAN", ARCH_MARKUP_NAME),  # a description decides before the name
        ('name="dental arch" radius_mm=1.2', ARCH_MARKUP_NAME),  # ctdrill's canal of that name
    ],
)
def test_a_curve_is_never_the_arch_by_a_word_in_its_name(
    tmp_path: Path, description: str, name: str | None
) -> None:
    plan = _read(tmp_path, [_LINE, _curve(description, name)])
    assert plan.arch_lps is None
    assert [lm.kind for lm in plan.landmarks] == ["canal"]


@pytest.mark.parametrize(
    ("description", "name", "file"),
    [
        ("arch", None, "case.mrk.json"),
        ("ARCH curve=polyline", "IAN canal", "case.mrk.json"),
        ("", ARCH_MARKUP_NAME, "case.mrk.json"),
        ("", "  Dental   Arch ", "case.mrk.json"),
    ],
)
def test_the_arch_is_marked_by_its_description_or_its_exact_name(
    tmp_path: Path, description: str, name: str | None, file: str
) -> None:
    plan = _read(tmp_path, [_LINE, _curve(description, name)], file)
    assert plan.landmarks == () and plan.arch_lps is not None


@pytest.mark.parametrize("file", [ARCH_MARKUP_NAME, "Dental Arch", "arch", "IAN canal"])
def test_no_role_or_name_comes_from_the_file_name(tmp_path: Path, file: str) -> None:
    """Slicer writes no markup name: an unnamed Curve is refused with the line telling the
    user to name it, whatever its file is called (a canal in "Dental Arch.mrk.json" used to
    become the arch: the drill went 1.6 mm deeper)."""
    (tmp_path / "line.mrk.json").write_text(json.dumps(slicer_document(_LINE)))
    (tmp_path / f"{file}.mrk.json").write_text(json.dumps(slicer_document(_curve())))
    with pytest.raises(PlanInputError) as info:
        load_plan_set([tmp_path])
    message = str(info.value)
    assert f"{file}.mrk.json: markups[0] (Curve) has no name: name the canal" in message
    assert "name=" in message and "\n" not in message
    run = run_cli_in_process(
        [
            "export",
            "--dicom",
            str(ASSETS / "demo" / "ct"),
            "--plan",
            str(tmp_path / "line.mrk.json"),
            "--plan",
            str(tmp_path / f"{file}.mrk.json"),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert run.code == 2 and run.stderr.count("\n") == 1 and "has no name" in run.stderr
    # named by its description (what Slicer keeps), the same file is a canal of that name
    (tmp_path / f"{file}.mrk.json").write_text(
        json.dumps(slicer_document(_curve('name="IAN canal" radius_mm=1.2')))
    )
    (plan,) = load_plan_set([tmp_path])
    assert plan.arch_lps is None
    assert [(lm.kind, lm.name) for lm in plan.landmarks] == [("canal", "IAN canal")]
    # marked as the arch by its description: the arch, whatever the file is called
    (tmp_path / f"{file}.mrk.json").write_text(json.dumps(slicer_document(_curve("arch"))))
    (plan,) = load_plan_set([tmp_path])
    assert plan.arch_lps is not None and plan.landmarks == ()


def test_an_arch_given_a_canal_setting_is_refused_naming_the_role(tmp_path: Path) -> None:
    with pytest.raises(PlanInputError) as info:
        _read(tmp_path, [_LINE, _curve("arch radius_mm=1.2")])
    message = str(info.value)
    assert "setting radius_mm" in message and "this Curve is the dental arch" in message


def test_is_arch_curve_reads_settings_not_words() -> None:
    assert is_arch_curve("arch", None)
    assert is_arch_curve(" Arch  curve=polyline", "anything")
    assert not is_arch_curve('name="arch" radius_mm=1', None)
    assert not is_arch_curve("the arch", None)
    assert not is_arch_curve(None, "arch")
    assert is_arch_curve(None, "dental arch")
    assert not is_arch_curve("canal", "dental arch")


# -- every markups file ctdrill writes reads back -------------------------------------------

_NAMES = st.one_of(
    st.sampled_from(
        [
            "arch",
            "dental arch",
            "Dental Arch",
            "IAN canal below the arch",
            'say "arch"',
            "arch curve=polyline",
            "name=arch",
            "x radius_mm=9",
            "back\\slash",
        ]
    ),
    st.text(
        alphabet=st.characters(blacklist_categories=("Cs", "Cc")), min_size=1, max_size=12
    ).filter(lambda s: s.strip() != ""),
)


@st.composite
def _plans(draw: st.DrawFn) -> tuple[Plan, ...]:
    canal_names = draw(st.lists(_NAMES, min_size=0, max_size=3, unique=True))
    point_names = draw(st.lists(_NAMES, min_size=0, max_size=2, unique=True))
    landmarks: list[CanalLandmark | PointLandmark] = []
    for i, name in enumerate(canal_names):
        n = draw(st.integers(1, 4))
        pts = np.array([[float(i), float(j), -float(j) - 1.0] for j in range(n)])
        landmarks.append(CanalLandmark(name, pts, radius_mm=1.0 + 0.5 * i))
    for i, name in enumerate(point_names):
        landmarks.append(PointLandmark(name, [float(i), 3.0, 4.0], margin_mm=1.5))
    arch = None
    if draw(st.booleans()):
        arch = np.array([[0.0, 0.0, 0.0], [10.0, 5.0, 0.0], [20.0, 0.0, 0.0]])
    names = draw(st.lists(_NAMES, min_size=1, max_size=3, unique=True))
    return tuple(
        Plan(
            entry_lps=[float(k), 0.0, 10.0],
            target_lps=[float(k), 0.0, 0.0],
            name=name,
            landmarks=tuple(landmarks),
            arch_lps=arch,
        )
        for k, name in enumerate(names)
    )


@settings(max_examples=40)
@given(plans=_plans())
def test_every_markups_file_ctdrill_writes_reads_back_as_the_same_plan(
    tmp_path_factory: pytest.TempPathFactory, plans: tuple[Plan, ...]
) -> None:
    path = tmp_path_factory.mktemp("rt") / "plan.mrk.json"
    path.write_text(json.dumps(plan_to_markups(plans)), encoding="utf-8")
    back = load_plan_set([path])
    assert [p.name for p in back] == [p.name for p in plans]
    first, again = plans[0], back[0]
    assert [(lm.kind, lm.name) for lm in again.landmarks] == [
        (lm.kind, lm.name) for lm in first.landmarks
    ]
    assert (again.arch_lps is None) == (first.arch_lps is None)
    if first.arch_lps is not None and again.arch_lps is not None:
        np.testing.assert_allclose(again.arch_lps, first.arch_lps, rtol=0, atol=1e-9)


def test_a_canal_too_long_for_a_slicer_curve_is_refused_when_written(tmp_path: Path) -> None:
    n = MAX_CURVE_POINTS + 1
    pts = np.stack([np.arange(n) * 0.01, np.sin(np.arange(n) * 0.37), np.zeros(n)], axis=1)
    plan = Plan(
        entry_lps=[0.0, 0.0, 10.0],
        target_lps=[0.0, 0.0, 0.0],
        landmarks=(CanalLandmark("dense canal", pts, radius_mm=1.0),),
    )
    out = tmp_path / "dense.mrk.json"
    with pytest.raises(PlanInputError, match=f"more than the {MAX_CURVE_POINTS} a Slicer Curve"):
        save_plan(plan, out)
    assert not out.exists()
    most = pts[:MAX_CURVE_POINTS]
    arch = Plan(entry_lps=[0.0, 0.0, 10.0], target_lps=[0.0, 0.0, 0.0], arch_lps=most)
    save_plan(arch, out)  # the longest arch a plan may hold reads back from a Slicer Curve
    (back,) = load_plan_set([out])
    assert back.arch_lps is not None
    np.testing.assert_array_equal(back.arch_lps, most)


def test_the_issue_case_through_the_cli_keeps_the_canal_and_its_stop(tmp_path: Path) -> None:
    """The demo's canal renamed "IAN canal below the arch": written as markups, read back by
    ``ctdrill plan``, exported: the canal binds at 10.8 mm as on the demo, not 12.0."""
    doc = json.loads((ASSETS / "demo" / "plan.json").read_text(encoding="utf-8"))
    doc["landmarks"][0]["name"] = "IAN canal below the arch"
    src = tmp_path / "case.json"
    src.write_text(json.dumps(doc), encoding="utf-8")
    mrk = tmp_path / "case.mrk.json"
    run = run_cli_in_process(["plan", str(src), "--out", str(mrk)])
    assert run.code == 0, run.stderr
    back = tmp_path / "back.json"
    run = run_cli_in_process(["plan", str(mrk), "--out", str(back)])
    assert run.code == 0, run.stderr
    out = tmp_path / "out"
    ct = str(ASSETS / "demo" / "ct")
    run = run_cli_in_process(
        ["export", "--dicom", ct, "--plan", str(mrk), "--out", str(out), "--rate-hz", "100"]
    )
    assert run.code == 0, run.stderr
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["stop_reason"] == "margin"
    assert summary["binding_landmark"]["name"] == "IAN canal below the arch"
    assert summary["stop_depth_mm"] == pytest.approx(10.8, abs=0.01)
    assert "no_landmarks" not in {w["code"] for w in summary["warnings"]}
