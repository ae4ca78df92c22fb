"""Defaults of ``ctdrill suggest`` (standard library only, so ``--help`` stays light)."""

from __future__ import annotations

#: Largest entry move (in the plane across the planned axis), mm.
DEFAULT_RADIUS_MM = 3.0
#: Largest tilt from the planned axis, degrees.
DEFAULT_CONE_DEG = 15.0
#: Candidates in all, the planned axis included.
DEFAULT_COUNT = 2000
#: Weights of the score's body, crest and apex terms: full cortical contact over the crest
#: zone is worth half the span from the bone to the cortical threshold in mean body HU
#: (550 HU), and so is the apex (docs/suggest.md).
DEFAULT_WEIGHTS = (1.0, 0.5, 0.5)
