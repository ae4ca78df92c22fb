"""One StopReason and one function that puts a stop into words."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ctdrill.engine.clearance import STOP_REASONS
from ctdrill.engine.stop import StopReason, stop_words

ROOT = Path(__file__).resolve().parents[2]


def test_the_reasons_are_the_summary_values() -> None:
    assert [r.value for r in StopReason] == ["planned_depth", "margin", "out_of_volume"]
    assert tuple(StopReason) == STOP_REASONS  # the tie order
    assert json.dumps({"stop_reason": StopReason.MARGIN}) == '{"stop_reason": "margin"}'
    assert StopReason("margin") == "margin"


@pytest.mark.parametrize(
    ("form", "reason", "words"),
    [
        ("code", "margin", "margin"),
        ("tag", "margin", "margin: 'canal', margin 2 mm"),
        ("tag", "planned_depth", "planned_depth"),
        ("plain", "out_of_volume", "end of the CT"),
        ("plain", "margin", "safety margin"),
        ("sentence", "margin", "the 2.00 mm margin of 'canal' at 10.80 mm (of 12.60 mm planned)"),
        ("sentence", "planned_depth", "the planned depth 12.60 mm"),
        (
            "sentence",
            "out_of_volume",
            "the end of the CT data at 10.80 mm (the drill would leave the scan)",
        ),
    ],
)
def test_stop_words(form: str, reason: str, words: str) -> None:
    at = {"landmark": "canal", "margin_mm": 2.0, "stop_mm": 10.8, "planned_mm": 12.6}
    assert stop_words(reason, form=form, **at) == words  # type: ignore[arg-type]


def test_a_margin_without_its_landmark() -> None:
    assert stop_words("margin") == "margin"
    assert stop_words("margin", form="sentence", stop_mm=3.0) == "the safety margin at 3.00 mm"
    with pytest.raises(ValueError):
        stop_words("deeper")


def test_no_output_words_a_stop_by_itself() -> None:
    """Only engine/stop.py maps the reasons to words: no other module spells one of their
    values in a comparison or a table of words."""
    values = {r.value for r in StopReason}
    offenders = []
    for room in ("app", "engine"):
        for path in sorted((ROOT / room).rglob("*.py")):
            rel = str(path.relative_to(ROOT))
            if rel == "engine/stop.py":
                continue
            text = path.read_text(encoding="utf-8")
            for v in values:
                for pattern in (f'== "{v}"', f'"{v}": "', f"== '{v}'"):
                    if pattern in text:
                        offenders.append(f"{rel}: {pattern}")
    assert offenders == []
