"""Plan edits as pure functions: exact results and refusals naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.app.errors import AppInputError
from ctdrill.app.gui import planning
from ctdrill.imaging.plan.landmarks import CanalLandmark, PointLandmark
from ctdrill.imaging.plan.types import Plan


def plan() -> Plan:
    return Plan(
        entry_lps=np.array([0.0, 0.0, 10.0]),
        target_lps=np.array([0.0, 0.0, 0.0]),
        landmarks=(
            CanalLandmark("canal", np.array([[-5.0, 0, -4], [5.0, 0, -4]]), radius_mm=1.2),
            PointLandmark("apex", np.array([3.0, 3.0, 3.0]), margin_mm=1.5),
        ),
    )


def test_move_handle_returns_a_new_plan() -> None:
    p = plan()
    moved = planning.move_handle(p, "target", np.array([0.0, 0.0, 4.0]))
    assert moved.planned_depth_mm == pytest.approx(6.0)
    assert p.planned_depth_mm == pytest.approx(10.0)  # unchanged
    entry = planning.move_handle(p, "entry", np.array([3.0, 4.0, 0.0]))
    assert entry.planned_depth_mm == pytest.approx(5.0)


@pytest.mark.parametrize(
    ("name", "point", "match"),
    [
        ("target", [0.0, 0.0, 10.2], "at least"),
        ("target", [np.nan, 0.0, 0.0], "finite"),
        ("tip", [0.0, 0.0, 0.0], "unknown handle"),
    ],
)
def test_move_handle_refuses_unusable_plans(name: str, point: list[float], match: str) -> None:
    with pytest.raises(AppInputError, match=match):
        planning.move_handle(plan(), name, np.array(point))


def test_margins_per_landmark() -> None:
    p = planning.set_landmark_margin(plan(), 0, 3.0)
    assert p.landmark_margin_mm(p.landmarks[0]) == 3.0
    assert p.landmark_margin_mm(p.landmarks[1]) == 1.5
    back = planning.set_landmark_margin(p, 0, None)
    assert back.landmark_margin_mm(back.landmarks[0]) == p.margin_mm
    with pytest.raises(AppInputError, match=r"landmarks\[1\].margin_mm"):
        planning.set_landmark_margin(p, 1, -1.0)


def test_remove_landmark() -> None:
    p = planning.remove_landmark(plan(), 0)
    assert [lm.name for lm in p.landmarks] == ["apex"]


def test_without_a_plan_two_placed_points_make_the_trajectory() -> None:
    assert not hasattr(planning, "default_plan")  # no trajectory is guessed for a new series
    first = planning.place_handle(None, {}, "target", np.array([1.0, 2.0, -1.0]))
    assert isinstance(first, dict) and set(first) == {"target"}
    again = planning.place_handle(None, first, "target", np.array([1.0, 2.0, -2.0]))
    assert isinstance(again, dict) and again["target"].tolist() == [1.0, 2.0, -2.0]
    made = planning.place_handle(None, again, "entry", np.array([1.0, 2.0, 7.0]))
    assert isinstance(made, Plan)
    assert made.entry_lps.tolist() == [1.0, 2.0, 7.0] and made.target_lps.tolist() == [1, 2, -2]
    assert made.planned_depth_mm == pytest.approx(9.0) and made.landmarks == ()
    with pytest.raises(AppInputError, match="at least"):
        planning.place_handle(None, first, "entry", np.array([1.0, 2.0, -0.9]))
    moved = planning.place_handle(made, {}, "target", np.array([1.0, 2.0, 0.0]))
    assert isinstance(moved, Plan) and moved.planned_depth_mm == pytest.approx(7.0)


def test_drawn_landmarks_are_unknown_without_a_result_for_the_plan() -> None:
    geoms = planning.drawn_landmarks(plan(), None)
    assert [g.clearance_mm for g in geoms] == [None, None]
    assert not any(g.violated for g in geoms)
    marked = planning.landmark_geometries(plan(), np.array([2.5, 4.0]), violated=1)
    assert [g.violated for g in marked] == [False, True]


def test_landmark_geometries_carry_margin_and_clearance() -> None:
    geoms = planning.landmark_geometries(plan(), np.array([2.5, 4.0]))
    assert [g.kind for g in geoms] == ["canal", "point"]
    assert [g.margin_mm for g in geoms] == [2.0, 1.5]
    assert [g.clearance_mm for g in geoms] == [2.5, 4.0]
    assert geoms[1].points_lps.shape == (1, 3) and geoms[1].radius_mm == 0.0
    stale = planning.landmark_geometries(plan(), np.array([2.5]))  # another landmark list
    assert [g.clearance_mm for g in stale] == [None, None]
