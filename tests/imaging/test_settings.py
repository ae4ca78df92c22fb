"""Settings in control-point descriptions: what ctdrill writes reads back exactly."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from ctdrill.imaging.plan.settings import format_settings, parse_settings

_names = st.text(min_size=1, max_size=40)
_numbers = st.floats(allow_nan=False, allow_infinity=False, width=64)


@given(name=_names, calibration=_names, diameter=_numbers, blades=st.integers(1, 100))
def test_written_settings_read_back_exactly(
    name: str, calibration: str, diameter: float, blades: int
) -> None:
    text = format_settings(
        {"name": name, "diameter_mm": diameter, "blades": blades, "calibration": calibration}
    )
    back = parse_settings(text)
    assert back == {
        "name": name,
        "diameter_mm": diameter,
        "blades": float(blades),
        "calibration": calibration,
    }
    assert math.copysign(1.0, back["diameter_mm"]) == math.copysign(1.0, diameter)


@given(prefix=st.text(alphabet=st.characters(exclude_characters='"='), max_size=30))
def test_free_text_around_settings_is_ignored(prefix: str) -> None:
    text = f"{prefix} radius_mm=1.5 {prefix}"
    assert parse_settings(text) == {"radius_mm": 1.5}


def test_quoted_values_hide_their_own_equals_signs() -> None:
    assert parse_settings('name="a b=c \\"d=e\\"" margin_mm=2') == {
        "name": 'a b=c "d=e"',
        "margin_mm": 2.0,
    }
    assert parse_settings("tip of the canal radius_mm=0.9, margin_mm=2;") == {
        "radius_mm": 0.9,
        "margin_mm": 2.0,
    }
