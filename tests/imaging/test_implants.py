"""Implants: body outline (closed forms), the generic library and user files, placement."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from ctdrill.imaging.plan.implants import (
    DEFAULT_LIBRARY,
    IMPLANTS_FORMAT,
    ImplantInputError,
    ImplantSpec,
    implant_placement,
    load_implant_library,
)
from ctdrill.imaging.plan.types import Plan


def test_flat_apex_profile_is_the_tapered_wall_then_the_flat_face() -> None:
    spec = ImplantSpec("t", diameter_mm=4.0, length_mm=10.0, apex_diameter_mm=3.0, apex="flat")
    s, r = spec.profile_mm()
    np.testing.assert_array_equal(s, [0.0, 10.0, 10.0])
    np.testing.assert_array_equal(r, [2.0, 1.5, 0.0])
    assert spec.radius_at_mm(5.0) == pytest.approx(1.75, abs=1e-15)
    assert spec.radius_at_mm(10.5) == 0.0


def test_round_apex_profile_is_a_hemisphere_ending_at_the_length() -> None:
    spec = ImplantSpec("r", diameter_mm=4.1, length_mm=10.0, apex_diameter_mm=2.9, apex="round")
    s, r = spec.profile_mm(n=33)
    assert (s[0], r[0]) == (0.0, 2.05)
    assert (s[-1], r[-1]) == (10.0, 0.0)
    assert np.all(np.diff(s) >= 0.0) and np.all(np.diff(r) <= 0.0)
    centre, ra = 10.0 - 1.45, 1.45
    np.testing.assert_allclose(np.hypot(s[1:] - centre, r[1:]), ra, rtol=0, atol=1e-12)
    # The side wall ends where the hemisphere begins, at the apex radius.
    assert (s[1], r[1]) == (pytest.approx(centre, abs=1e-12), pytest.approx(ra, abs=1e-12))
    # Half-way up the cap (s = centre + ra sin 30deg) the radius is ra cos 30deg.
    assert spec.radius_at_mm(centre + ra / 2) == pytest.approx(ra * math.sqrt(3) / 2, abs=1e-12)
    assert spec.radius_at_mm(centre / 2) == pytest.approx((2.05 + ra) / 2, abs=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"diameter_mm": float("nan")}, "diameter_mm"),
        ({"length_mm": 1e9}, "length_mm"),
        ({"apex_diameter_mm": 5.0}, "apex_diameter_mm"),
        ({"apex": "pointy"}, "apex"),
        ({"name": " "}, "name"),
        ({"apex": "round", "length_mm": 1.0}, "length_mm"),
    ],
)
def test_bad_specs_are_refused_naming_the_field(kwargs: dict[str, object], field: str) -> None:
    base: dict[str, object] = {
        "name": "x",
        "diameter_mm": 4.0,
        "length_mm": 10.0,
        "apex_diameter_mm": 3.0,
        "apex": "flat",
    }
    with pytest.raises(ImplantInputError, match=field):
        ImplantSpec(**(base | kwargs))  # type: ignore[arg-type]


def test_generic_library_holds_every_size_in_both_shapes() -> None:
    lib = load_implant_library()
    doc = json.loads(DEFAULT_LIBRARY.read_text(encoding="utf-8"))
    assert doc["format"] == IMPLANTS_FORMAT
    assert len(lib) == len(doc["implants"]) == 2 * 5 * 4
    sizes = {(s.diameter_mm, s.length_mm, s.apex) for s in lib}
    for d in (3.3, 3.5, 4.1, 4.8, 5.0):
        for length in (8.0, 10.0, 11.5, 13.0):
            assert (d, length, "flat") in sizes and (d, length, "round") in sizes
    assert all(s.apex_diameter_mm < s.diameter_mm for s in lib if s.apex == "round")
    assert len({s.name for s in lib}) == len(lib)


def test_user_file_extends_and_overrides_by_name(tmp_path: Path) -> None:
    lib = load_implant_library()
    first = lib[0]
    user = tmp_path / "mine.json"
    mine = [
        {"name": first.name, "diameter_mm": 3.0, "length_mm": 9.0, "apex_diameter_mm": 2.0,
         "apex": "round"},
        {"name": "short 6.0 x 6", "diameter_mm": 6.0, "length_mm": 6.0,
         "apex_diameter_mm": 6.0, "apex": "flat"},
    ]  # fmt: skip
    user.write_text(json.dumps({"format": IMPLANTS_FORMAT, "implants": mine}), encoding="utf-8")
    both = load_implant_library(user)
    assert len(both) == len(lib) + 1
    assert both[0] == ImplantSpec(first.name, 3.0, 9.0, 2.0, "round")
    assert both[-1] == ImplantSpec("short 6.0 x 6", 6.0, 6.0, 6.0, "flat")
    assert both[1:-1] == lib[1:]


def _item(**kw: object) -> dict[str, object]:
    base: dict[str, object] = {
        "name": "a",
        "diameter_mm": 4,
        "length_mm": 10,
        "apex_diameter_mm": 3,
        "apex": "flat",
    }
    return base | kw


@pytest.mark.parametrize(
    ("doc", "expected"),
    [
        ({"format": "x", "implants": []}, 'mine.json: format must be "ctdrill-implants/1"'),
        ({"format": IMPLANTS_FORMAT, "implants": []}, "mine.json: implants must be a non-empty"),
        (
            {"format": IMPLANTS_FORMAT, "implants": [{"name": "a"}]},
            "mine.json: implants[0].diameter_mm is missing",
        ),
        (
            {"format": IMPLANTS_FORMAT, "implants": [_item(diameter_mm="4")]},
            "mine.json: implants[0].diameter_mm must be a positive number",
        ),
        (
            {"format": IMPLANTS_FORMAT, "implants": [_item(brand="x")]},
            "mine.json: implants[0].brand is not a known field",
        ),
        (
            {"format": IMPLANTS_FORMAT, "implants": [_item(), _item(length_mm=11)]},
            "mine.json: implants[1].name 'a' is listed twice",
        ),
    ],
)
def test_bad_library_files_are_refused_naming_file_and_field(
    tmp_path: Path, doc: dict[str, object], expected: str
) -> None:
    user = tmp_path / "mine.json"
    user.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(ImplantInputError) as info:
        load_implant_library(user)
    assert str(info.value).startswith(expected)
    assert "\n" not in str(info.value)


def test_library_file_with_nan_or_not_a_file_is_refused(tmp_path: Path) -> None:
    user = tmp_path / "mine.json"
    user.write_text('{"format": "ctdrill-implants/1", "implants": [NaN]}', encoding="utf-8")
    with pytest.raises(ImplantInputError, match=r"mine\.json"):
        load_implant_library(user)
    with pytest.raises(ImplantInputError, match="not a regular file"):
        load_implant_library(tmp_path)


def test_placement_puts_the_apex_on_the_target_and_the_platform_length_back() -> None:
    spec = ImplantSpec("x", 4.0, 10.0, 3.0, "flat")
    plan = Plan(entry_lps=[0.0, 0.0, 0.0], target_lps=[3.0, 4.0, 12.0], implant=spec)
    place = implant_placement(plan)
    assert place is not None
    axis = np.array([3.0, 4.0, 12.0]) / 13.0
    np.testing.assert_allclose(place.axis_lps, axis, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(place.apex_lps, [3.0, 4.0, 12.0])
    np.testing.assert_allclose(place.platform_lps, axis * 3.0, rtol=0, atol=1e-14)
    assert (place.platform_depth_mm, place.apex_depth_mm) == (pytest.approx(3.0), 13.0)
    np.testing.assert_allclose(place.point_at_mm(10.0), place.apex_lps, rtol=0, atol=1e-14)
    assert implant_placement(Plan(entry_lps=[0, 0, 0], target_lps=[0, 0, 1])) is None
