"""The implant body of a plan as drawing geometry: base, axis and radius profile.

Reads :func:`ctdrill.imaging.plan.implants.implant_placement` (the apex at the planned target,
the platform ``length_mm`` back along the axis) and :meth:`ImplantSpec.profile_mm`, the one
owner of the implant's shape.
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.plan.types import Plan


def implant_body(plan: Plan) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, str] | None:
    """(platform_lps, axis_lps, s_mm, r_mm, spec name) of the plan's implant, or None."""
    from ctdrill.imaging.plan.implants import implant_placement

    placement = implant_placement(plan)
    if placement is None:
        return None
    s_mm, r_mm = placement.spec.profile_mm()
    return (
        np.asarray(placement.platform_lps, dtype=np.float64),
        np.asarray(placement.axis_lps, dtype=np.float64),
        np.asarray(s_mm, dtype=np.float64),
        np.asarray(r_mm, dtype=np.float64),
        str(placement.spec.name),
    )
