"""Implant warnings: the stop against the apex, the platform against the entry, implant gaps."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.imaging.plan.implant_checks import (
    implant_gap_mm,
    implant_warnings,
    implants_too_close,
    segment_distance_mm,
)
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.types import Plan

SPEC = ImplantSpec("t 4 x 10", diameter_mm=4.0, length_mm=10.0, apex_diameter_mm=3.0, apex="round")


def _plan(x: float, *, depth: float = 12.0, name: str = "a", tilt: float = 0.0) -> Plan:
    return Plan(
        entry_lps=[x, 0.0, 0.0], target_lps=[x + tilt, 0.0, -depth], implant=SPEC, name=name
    )


def test_a_stop_shallower_than_the_apex_warns_and_the_planned_depth_does_not() -> None:
    plan = _plan(0.0)
    assert implant_warnings(plan, 12.0, "planned_depth") == ()
    (warning,) = implant_warnings(plan, 10.8, "margin")
    code, msg = warning.code, warning.message
    assert code == "implant_beyond_stop"
    assert "12.00 mm deep" in msg and "stops at 10.80 mm (margin)" in msg
    assert implant_warnings(Plan(entry_lps=[0, 0, 0], target_lps=[0, 0, 1]), 0.5, "margin") == ()


def test_an_implant_longer_than_the_planned_depth_stands_above_the_entry() -> None:
    (warning,) = implant_warnings(_plan(0.0, depth=8.5), 8.5, "planned_depth")
    code, msg = warning.code, warning.message
    assert code == "implant_above_entry" and "1.50 mm above the entry point" in msg
    assert implant_warnings(_plan(0.0, depth=10.0), 10.0, "planned_depth") == ()


@pytest.mark.parametrize(
    ("p", "q", "expected"),
    [
        # Parallel, side by side: the distance between the lines.
        (([0, 0, 0], [0, 0, 10]), ([3, 4, 2], [3, 4, 12]), 5.0),
        # Skew and crossing in projection: the common perpendicular (z offset).
        (([-1, 0, 0], [1, 0, 0]), ([0, -1, 2], [0, 1, 2]), 2.0),
        # Collinear, apart end to end.
        (([0, 0, 0], [0, 0, 1]), ([0, 0, 4], [0, 0, 9]), 3.0),
        # The nearest points are end points of both (clamped).
        (([0, 0, 0], [1, 0, 0]), ([4, 4, 0], [4, 9, 0]), 5.0),
        # A degenerate segment (a point) against a segment.
        (([0, 0, 5], [0, 0, 5]), ([3, 0, 0], [3, 0, 10]), 3.0),
    ],
)
def test_segment_distance_closed_forms(
    p: tuple[list[float], list[float]], q: tuple[list[float], list[float]], expected: float
) -> None:
    arr = [np.asarray(v, dtype=np.float64) for v in (*p, *q)]
    assert segment_distance_mm(*arr) == pytest.approx(expected, abs=1e-12)
    assert segment_distance_mm(arr[2], arr[3], arr[0], arr[1]) == pytest.approx(expected, abs=1e-12)


def test_parallel_implants_gap_is_between_their_platforms() -> None:
    a, b = _plan(0.0, name="a"), _plan(6.5, name="b")
    assert implant_gap_mm(a, b) == pytest.approx(6.5 - 4.0, abs=1e-12)
    warned = implants_too_close((a, b, _plan(30.0, name="far")))
    assert set(warned) == {"a", "b"}
    (warning,) = warned["a"]
    code, msg = warning.code, warning.message
    assert code == "implants_too_close" and "2.50 mm apart" in msg and warned["b"] == warned["a"]
    assert implants_too_close((a, _plan(7.0, name="c"))) == {}  # exactly 3 mm is kept


def test_gap_without_an_implant_is_none_and_sets_without_pairs_are_quiet() -> None:
    bare = Plan(entry_lps=[1, 0, 0], target_lps=[1, 0, -10], name="bare")
    assert implant_gap_mm(_plan(0.0), bare) is None
    assert implants_too_close((_plan(0.0), bare)) == {}


def test_intersecting_implants_are_said_to_intersect() -> None:
    a, b = _plan(0.0, name="a"), _plan(2.0, name="b")
    (warning,) = implants_too_close((a, b))["a"]
    msg = warning.message
    assert "intersect" in msg and "mm of overlap" in msg and "apart" not in msg
