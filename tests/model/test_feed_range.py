"""A calibration set owns its feed range; feeds beyond it, or beyond the model's cap, are said."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ctdrill.model.calibration import (
    CalibrationError,
    calibration_from_dict,
    calibration_to_dict,
    load_calibration,
)
from ctdrill.model.force import MAX_FEED_MM_S, a0_n, feed_outside_model


def test_bundled_sets_name_the_feeds_they_were_calibrated_at() -> None:
    # the paper, section 3.1: "The feed velocity was ranged from 0.1 mm/s to 0.5 mm/s"
    assert load_calibration("pine-wood-paper").feed_range_mm_s == (0.1, 0.5)
    # anchored at 0.6 mm/s (cortical bone, the paper's introduction)
    assert load_calibration("bone-illustrative").feed_range_mm_s == (0.1, 0.6)


def test_a_set_without_feed_range_stays_valid_and_round_trips(tmp_path: Path) -> None:
    doc = calibration_to_dict(load_calibration("pine-wood-paper"))
    assert doc["feed_range_mm_s"] == [0.1, 0.5]
    del doc["feed_range_mm_s"]
    old = calibration_from_dict(doc, source_path=tmp_path / "old.json")
    assert old.feed_range_mm_s is None
    assert "feed_range_mm_s" not in calibration_to_dict(old)
    for bad in ([0.5, 0.1], [-1, 1], [1], "fast"):
        with pytest.raises(CalibrationError, match="feed_range_mm_s"):
            calibration_from_dict({**doc, "feed_range_mm_s": bad}, source_path="x.json")
    (tmp_path / "s.json").write_text(json.dumps({**doc, "feed_range_mm_s": [0.2, 0.2]}))
    assert load_calibration(tmp_path / "s.json").feed_range_mm_s == (0.2, 0.2)


def test_feed_outside_model_says_extrapolated_and_capped() -> None:
    cal = load_calibration("bone-illustrative")
    assert feed_outside_model(0.4, cal) is None
    assert feed_outside_model(0.1, cal) is None and feed_outside_model(0.6, cal) is None
    low = feed_outside_model(0.05, cal)
    assert low is not None and "0.1..0.6 mm/s" in low and "capped" not in low
    high = feed_outside_model(200.0, cal)
    assert high is not None and "extrapolated" in high and f"capped at {MAX_FEED_MM_S:g}" in high
    # Eq. 19's DC term at 200 mm/s over the capped one: (1 + 0.25 * 200) / (1 + 0.25 * 50)
    ratio = (1 + 0.25 * 200.0) / (1 + 0.25 * MAX_FEED_MM_S)
    assert f"{ratio:.3g} x" in high
    assert float(a0_n(1500.0, 200.0, cal)) == pytest.approx(float(a0_n(1500.0, 50.0, cal)))
    # a set that names no range: only the cap is a reason
    old = calibration_from_dict(
        {k: v for k, v in calibration_to_dict(cal).items() if k != "feed_range_mm_s"}
    )
    assert feed_outside_model(5.0, old) is None
    assert "capped" in (feed_outside_model(51.0, old) or "")
