"""The implant site as an FDI tooth number (ISO 3950): the plan key ``site``.

Two digits: the quadrant (1 upper right, 2 upper left, 3 lower left, 4 lower right, the
patient's sides) and the tooth counted from the midline (1 central incisor ... 8 third
molar): 11-18, 21-28, 31-38, 41-48. Deciduous quadrants (5-8) are refused: implants replace
permanent teeth.
"""

from __future__ import annotations

import math

#: Quadrants of the permanent dentition: number -> (jaw, the patient's side).
FDI_QUADRANTS: dict[int, tuple[str, str]] = {
    1: ("upper", "right"),
    2: ("upper", "left"),
    3: ("lower", "left"),
    4: ("lower", "right"),
}
#: Teeth of a quadrant, counted from the midline.
FDI_TEETH: dict[int, str] = {
    1: "central incisor",
    2: "lateral incisor",
    3: "canine",
    4: "first premolar",
    5: "second premolar",
    6: "first molar",
    7: "second molar",
    8: "third molar",
}
#: What a refusal says a site must be.
SITE_RULE = "an FDI tooth number 11-48 (quadrant 1-4, then tooth 1-8: e.g. 36)"


def site_error(value: object) -> str | None:
    """Why ``value`` is not an FDI site, or None when it is one.

    A whole number (an integral float such as Slicer's ``36.0`` counts); its tens digit a
    quadrant 1-4, its units a tooth 1-8.
    """
    if isinstance(value, bool) or not isinstance(value, int | float):
        return f"must be {SITE_RULE}"
    if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
        return f"must be {SITE_RULE}"
    number = int(value)
    quadrant, tooth = divmod(number, 10)
    if quadrant not in FDI_QUADRANTS:
        return f"must be {SITE_RULE}; quadrant {quadrant} is not 1-4"
    if tooth not in FDI_TEETH:
        return f"must be {SITE_RULE}; tooth {tooth} is not 1-8"
    return None


def site_text(site: int) -> str:
    """``36 (lower left first molar)``: the number and what it names."""
    quadrant, tooth = divmod(int(site), 10)
    jaw, side = FDI_QUADRANTS[quadrant]
    return f"{site} ({jaw} {side} {FDI_TEETH[tooth]})"


def site_jaw(site: int) -> str:
    """``"upper"`` (maxilla) or ``"lower"`` (mandible)."""
    return FDI_QUADRANTS[int(site) // 10][0]
