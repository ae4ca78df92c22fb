"""The debrief in plain words: the sentences a student reads, the field names in the tooltips."""

from __future__ import annotations

from typing import Any

from ctdrill.app.trainee.words import assessment_line, debrief_lines, next_time
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS

#: The demo's 300 ms reaction in exam mode (docs/rehearse.md's table).
EXAM: dict[str, Any] = {
    "depth_error_mm": 6.4285,
    "overshoot_mm": 6.4285,
    "breach": True,
    "time_in_margin_s": 2.643,
    "canal_entered": True,
    "peak_hand_force_n": 12.2,
    "mean_hand_force_n": 11.889,
    "time_to_planned_s": 2.357,
    "feed_cv": 0.4227,
    "reaction_ms": 311.0,
    "wall_contacts": 0,
    "peak_wall_force_n": 0.0,
    "goal_depth_mm": 10.8,
    "attempted": True,
    "hand_force_cv": 0.02,
    "plunge_mm": 3.9,
    "wall_press_s": 0.0,
    "wall_overrun_mm": 0.0,
    "display_lag_ms": None,
    "display_lagged": False,
    "score": 3.9,
}
#: A perfect guarded session: the wall at the margin, let go 150 ms later.
GUARDED: dict[str, Any] = EXAM | {
    "depth_error_mm": 0.0,
    "overshoot_mm": 0.0,
    "breach": False,
    "time_in_margin_s": 0.0,
    "canal_entered": False,
    "feed_cv": 0.4856,
    "reaction_ms": None,
    "plunge_mm": 0.0,
    "wall_contacts": 1,
    "wall_press_s": 0.153,
    "wall_overrun_mm": 1.09,
    "peak_wall_force_n": 20.894,
    "score": 100.0,
}
#: Engineering words that belong in the tooltips and summary.json, not in the sentences.
ENGINEERING = ("_mm", "_n", "_s", "S0", "I2t", "RFOB", "cv", "overshoot", "breach")


def test_an_exam_breach_in_plain_words() -> None:
    lines = debrief_lines(EXAM, planned_depth_mm=12.6)
    assert [line.text for line in lines] == [
        "Score: 4 of 100",
        "You drilled to 17.23 mm, 6.43 mm past the goal (10.80 mm).",
        "You went 6.43 mm past the safe depth, into the safety zone around the nerve, for "
        "2.64 s. The drill entered the canal itself.",
        "Your push: up to 12.2 N, 11.9 N on average.",
        "Your push was steady (it varied by 2 %).",
        "You reached the goal after 2.4 s.",
        "When the bone gave way you let go after 311 ms; the drill went 3.90 mm further.",
        "You did not meet the stop.",
        "Next time: let go by 10.8 mm, 6.4 mm sooner, pushing about 12 N.",
    ]
    assert [line.bad for line in lines] == [
        False,
        True,
        True,
        False,
        False,
        False,
        True,
        False,
        False,
    ]
    assert lines[2].tooltip(EXAM) == (
        "breach = True\novershoot_mm = 6.4285\ntime_in_margin_s = 2.643\ncanal_entered = True"
    )
    # every field is named in some tooltip, and none in the sentences
    named = {f for line in lines for f in line.fields}
    assert named == set(ASSESSMENT_FIELDS)
    for line in lines:
        assert not any(word in line.text for word in ENGINEERING), line.text
    assert assessment_line({"assessment": EXAM, "planned_depth_mm": 12.6}) == (
        "assessment: score 3.9/100; drilled to 17.23 mm of the 10.80 mm goal; breach: 6.43 mm "
        "past the max safe depth, 2.64 s in the margin, the canal entered"
    )


def test_a_guarded_session_at_the_wall_is_correct_and_says_what_next() -> None:
    lines = debrief_lines(GUARDED, planned_depth_mm=12.6)
    texts = [line.text for line in lines]
    # the stop at the guard is the best result, not "1.80 mm short"
    assert texts[0] == "Score: 100 of 100"
    assert texts[1] == "The wall stopped you at the margin, at 10.80 mm: correct."
    assert texts[2] == "You stayed out of the safety zone around the nerve."
    assert "You reached the goal after 2.4 s." in texts
    # a constant push is steady whatever the bone's layers do to the feed
    assert "Your push was steady (it varied by 2 %)." in texts
    assert "The drill did not break out of the last layer before the goal." in texts
    assert texts[-2] == (
        "You met the stop once and pressed on it for 0.2 s; it pushed back with up to 20.9 N."
    )
    assert texts[-1] == "Next time: the same: push about 12 N and let go at 10.8 mm."
    assert not any(line.bad for line in lines)


def test_next_time_names_the_numbers_of_the_first_thing_to_fix() -> None:
    cases = [
        (GUARDED | {"peak_hand_force_n": 30.5, "mean_hand_force_n": 30.1}, "push at most 20 N"),
        (GUARDED | {"wall_press_s": 2.6}, "let go within 0.5 s of meeting the stop (you pressed"),
        (GUARDED | {"hand_force_cv": 0.2}, "hold an even push of about 12 N"),
        (GUARDED | {"depth_error_mm": -1.5}, "drill 1.5 mm deeper, to 10.8 mm"),
        (
            GUARDED | {"depth_error_mm": -5.0, "attempted": False, "score": 0.0},
            "push harder than 12 N and drill on to 10.8 mm",
        ),
        (EXAM | {"reaction_ms": 90.0, "overshoot_mm": 1.25}, "1.2 mm sooner, pushing about 12 N"),
    ]
    for fields, words in cases:
        assert words in next_time(fields).text, (fields, next_time(fields).text)
    lagged = EXAM | {"display_lag_ms": 435.0, "display_lagged": True}
    line = debrief_lines(lagged, planned_depth_mm=12.6)[6]
    assert line.text == "The screen lagged by up to 435 ms, so your reaction is not scored."
    fault = {"outcome": "fault", "reason": "device_fault: the device raised watchdog"}
    lines = debrief_lines(GUARDED, planned_depth_mm=12.6, summary=fault)
    assert "fault of the device or its link" in lines[1].text and lines[1].bad
    assert lines[-1].text == "Next time: rehearse again: this session is not graded."
