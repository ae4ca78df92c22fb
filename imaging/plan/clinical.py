"""Clinical reference distances (DESIGN.md section 5), each defined here once.

Below the plan's value types: :class:`~ctdrill.imaging.plan.types.Plan` takes its defaults
(margin, bone wall) from here and :mod:`ctdrill.imaging.plan.safety` reports margins below the
clinical one, so neither owns the number the other needs.
"""

from __future__ import annotations

#: Clinical safety margin to the inferior alveolar nerve canal, from the implant and the drill
#: tip, mm (CBCT under-measures sub-mm gaps by 0.2-0.3 mm). The default margin of a plan;
#: margins below it are reported (warning ``margin_below_clinical``).
CLINICAL_MARGIN_MM = 2.0
#: Thinnest bone wall to keep around an implant, mm (at least 1.5 mm of bone around the
#: implant, buccal above all): the default of a trajectory's ``min_wall_mm``; thinner walls are
#: reported (warning ``thin_wall``).
CLINICAL_MIN_WALL_MM = 1.5
#: Clinical minimum distance from an implant to a neighbouring tooth, mm (DESIGN.md section 5;
#: warning ``implant_near_tooth``).
CLINICAL_TOOTH_DISTANCE_MM = 1.5
