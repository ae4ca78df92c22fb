"""Defaults of ``ctdrill suggest`` (standard library only, so ``--help`` stays light)."""

from __future__ import annotations

#: Largest entry move (in the plane across the planned axis), mm.
DEFAULT_RADIUS_MM = 3.0
#: Largest tilt from the planned axis, degrees.
DEFAULT_CONE_DEG = 15.0
#: Candidates in all, the planned axis included.
DEFAULT_COUNT = 2000
#: Weights of the score's body, crest and apex terms: bone around the implant, no reward for
#: cortical contact (an axis pressed against a plate has one thin wall; docs/suggest.md).
DEFAULT_WEIGHTS = (1.0, 0.0, 0.0)
#: Weight of the even-walls term of the checked candidates: perfectly even walls are worth
#: the span from the bone to the cortical threshold in mean body HU (1100 HU).
DEFAULT_BALANCE_WEIGHT = 1.0
