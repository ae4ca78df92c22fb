"""The debrief in plain words: the sentences a student reads, the field names in the tooltips."""

from __future__ import annotations

from typing import Any

from ctdrill.app.trainee.words import assessment_line, debrief_lines
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS

#: The demo's 300 ms reaction in exam mode (docs/rehearse.md's table).
EXAM: dict[str, Any] = {
    "depth_error_mm": 5.2277,
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
    "score": 3.9,
}
#: A guarded session that met the stop twice and never broke through.
GUARDED: dict[str, Any] = EXAM | {
    "depth_error_mm": -1.2008,
    "overshoot_mm": 0.0,
    "breach": False,
    "time_in_margin_s": 0.0,
    "canal_entered": False,
    "time_to_planned_s": None,
    "feed_cv": 0.1,
    "reaction_ms": None,
    "wall_contacts": 2,
    "peak_wall_force_n": 20.894,
    "score": 77.8,
}
#: Engineering words that belong in the tooltips and summary.json, not in the sentences.
ENGINEERING = ("_mm", "_n", "_s", "S0", "I2t", "RFOB", "cv", "overshoot", "breach")


def test_an_exam_breach_in_plain_words() -> None:
    lines = debrief_lines(EXAM, planned_depth_mm=12.0)
    assert [line.text for line in lines] == [
        "Score: 4 of 100",
        "You drilled to 17.23 mm; the plan asked for 12.00 mm (5.23 mm too deep).",
        "You went 6.43 mm past the safe depth, into the safety zone around the nerve, for "
        "2.64 s. The drill entered the canal itself.",
        "Your push: up to 12.2 N, 11.9 N on average.",
        "You reached the end of the planned hole after 2.4 s.",
        "Your advance was fairly steady (it varied by 42 %).",
        "When the bone gave way you let go after 311 ms.",
        "You did not meet the stop.",
    ]
    assert [line.bad for line in lines] == [False, False, True, False, False, False, True, False]
    assert lines[2].tooltip(EXAM) == (
        "breach = True\novershoot_mm = 6.4285\ntime_in_margin_s = 2.643\ncanal_entered = True"
    )
    # every field is named in some tooltip, and none in the sentences
    named = {f for line in lines for f in line.fields}
    assert named == set(ASSESSMENT_FIELDS)
    for line in lines:
        assert not any(word in line.text for word in ENGINEERING), line.text
    assert assessment_line({"assessment": EXAM, "planned_depth_mm": 12.0}) == (
        "assessment: score 3.9/100; drilled to 17.23 mm of 12.00 mm planned; breach: 6.43 mm "
        "past the max safe depth, 2.64 s in the margin, the canal entered"
    )


def test_a_guarded_session_in_plain_words() -> None:
    texts = [line.text for line in debrief_lines(GUARDED, planned_depth_mm=12.0)]
    assert texts[1] == "You drilled to 10.80 mm; the plan asked for 12.00 mm (1.20 mm short)."
    assert texts[2] == "You stayed out of the safety zone around the nerve."
    assert "You did not reach the end of the planned hole." in texts
    assert "Your advance was steady (it varied by 10 %)." in texts
    assert "The drill did not break through into softer tissue." in texts
    assert texts[-1] == "You met the stop 2 times; it pushed back with up to 20.9 N."
