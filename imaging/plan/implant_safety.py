"""The implant body as a protected object: its exact clearance to every landmark and margin.

The implant at its placement (:func:`~ctdrill.imaging.plan.implants.implant_placement`: apex
at the target, platform ``length_mm`` back along the axis) is a convex solid of revolution
(:class:`ImplantBody`), measured by the same exact routine as the swept drill
(:mod:`ctdrill.imaging.plan.revolution`), so every landmark kind answers for it through its
own ``clearance_mm`` (:mod:`ctdrill.imaging.plan.landmark_base`). Clearances are signed:
minus the penetration depth inside a landmark (DESIGN.md section 4).

Which landmark binds: the one with the least slack ``clearance - margin`` (each landmark's own
margin, else the plan's); with one margin for all, that is the nearest landmark.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ctdrill.imaging.plan.distance import axial_coordinates
from ctdrill.imaging.plan.implants import ImplantSpec, implant_placement
from ctdrill.imaging.plan.landmark_base import Landmark
from ctdrill.imaging.plan.revolution import Meridian, body_meridian
from ctdrill.imaging.plan.types import Plan
from ctdrill.warning_codes import LoadWarning


@dataclass(frozen=True, eq=False)
class ImplantBody:
    """An implant on a trajectory's axis (LPS mm), placed by the depth of its apex.

    Attributes
    ----------
    entry_lps : (3,) depth 0 of the axis.
    direction : (3,) unit vector entry -> target (platform -> apex).
    spec : the implant's shape.
    apex_depth_mm : where the plan places the apex (the planned target's depth), mm.
    meridian : the body's meridian (tip at ``u = 0``; a round apex as the convex hull,
        :func:`~ctdrill.imaging.plan.revolution.body_meridian`).
    """

    entry_lps: np.ndarray
    direction: np.ndarray
    spec: ImplantSpec
    apex_depth_mm: float
    meridian: Meridian = field(init=False, repr=False)

    def __post_init__(self) -> None:
        entry = np.array(self.entry_lps, dtype=np.float64).reshape(3)
        u = np.array(self.direction, dtype=np.float64).reshape(3)
        norm = float(np.linalg.norm(u))
        if not (np.all(np.isfinite(entry)) and np.isfinite(norm) and norm > 0.0):
            raise ValueError("implant axis: entry and direction must be finite, direction non-zero")
        u = u / norm
        for name, arr in (("entry_lps", entry), ("direction", u)):
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        spec = self.spec
        meridian = body_meridian(
            spec.radius_mm,
            spec.length_mm,
            spec.apex_diameter_mm / 2.0,
            round_apex=spec.apex == "round",
        )
        object.__setattr__(self, "apex_depth_mm", float(self.apex_depth_mm))
        object.__setattr__(self, "meridian", meridian)

    def signed_distance_mm(self, points_lps: np.ndarray, depth_mm: np.ndarray) -> np.ndarray:
        """Signed distance from points (..., 3) LPS mm to the body with its apex at
        ``depth_mm`` (broadcast), mm; < 0 inside."""
        s, perp = axial_coordinates(points_lps, self.entry_lps, self.direction)
        return self.meridian.signed_distance_mm(
            s - np.asarray(depth_mm, dtype=np.float64), np.linalg.norm(perp, axis=-1)
        )

    def distance_at_placement_mm(self, points_lps: np.ndarray) -> np.ndarray:
        """:meth:`signed_distance_mm` with the apex where the plan puts it, mm."""
        return self.signed_distance_mm(points_lps, np.asarray(self.apex_depth_mm))


def implant_body(plan: Plan) -> ImplantBody | None:
    """The body of ``plan``'s implant at its placement; None without an implant."""
    place = implant_placement(plan)
    if place is None:
        return None
    return ImplantBody(plan.entry_lps, plan.direction, place.spec, place.apex_depth_mm)


def implant_clearances_mm(body: ImplantBody, landmarks: tuple[Landmark, ...]) -> np.ndarray:
    """(L,) signed clearance from the placed body to each landmark, mm: exact to
    :data:`~ctdrill.imaging.plan.distance.SEGMENT_TOL_MM` and never above the true value by
    more than that; a round apex on a tapered side is measured on the body's convex hull, at
    most :func:`~ctdrill.imaging.plan.revolution.hull_excess_mm` (< 0.01 mm for the library)
    nearer than the body itself.

    Mask landmarks must have a grid (:func:`~ctdrill.imaging.plan.landmarks.bind_to_grid`).
    """
    depth = np.array([body.apex_depth_mm])
    return np.array([float(lm.clearance_mm(body, depth)[0]) for lm in landmarks])


@dataclass(frozen=True, eq=False)
class ImplantClearance:
    """The implant body against the plan's landmarks.

    Attributes
    ----------
    clearance_mm : (L,) signed clearance to each landmark, mm.
    margins_mm : (L,) the margin that applies to each (its own, else the plan's), mm.
    names : (L,) the landmarks' names.
    binding : index of the landmark with the least slack (``clearance - margin``).
    """

    clearance_mm: np.ndarray
    margins_mm: np.ndarray
    names: tuple[str, ...]
    binding: int

    @property
    def binding_clearance_mm(self) -> float:
        """The binding landmark's clearance, mm (``implant_clearance_mm`` of a summary)."""
        return float(self.clearance_mm[self.binding])

    @property
    def violated(self) -> tuple[int, ...]:
        """Indices of the landmarks whose margin the implant breaks."""
        return tuple(int(i) for i in np.flatnonzero(self.clearance_mm < self.margins_mm))

    def to_json(self) -> dict[str, Any]:
        """``implant_clearance_mm`` and ``implant_binding_landmark`` (``name``, ``margin_mm``)
        as a summary writes them."""
        return {
            "implant_clearance_mm": self.binding_clearance_mm,
            "implant_binding_landmark": {
                "name": self.names[self.binding],
                "margin_mm": float(self.margins_mm[self.binding]),
            },
        }


def implant_clearance(
    plan: Plan, landmarks: tuple[Landmark, ...] | None = None
) -> ImplantClearance | None:
    """The clearance of ``plan``'s implant body to its landmarks (or ``landmarks``, bound to
    the CT grid when masks need it); None without an implant or without a landmark."""
    body = implant_body(plan)
    lms = plan.landmarks if landmarks is None else landmarks
    if body is None or not lms:
        return None
    clear = implant_clearances_mm(body, lms)
    margins = np.array([plan.landmark_margin_mm(lm) for lm in lms], dtype=np.float64)
    binding = int(np.argmin(clear - margins))
    return ImplantClearance(clear, margins, tuple(lm.name for lm in lms), binding)


def broken_margins_text(result: ImplantClearance) -> str:
    """Every landmark whose margin the body breaks, its clearance and margin, in words
    (``'canal' 0.80 mm (margin 2 mm)``, comma-separated); empty when none is broken."""
    return ", ".join(
        f"{result.names[i]!r} {float(result.clearance_mm[i]):.2f} mm (margin "
        f"{float(result.margins_mm[i]):g} mm"
        + (", inside it)" if result.clearance_mm[i] < 0 else ")")
        for i in result.violated
    )


def implant_margin_warnings(plan: Plan, result: ImplantClearance | None) -> list[LoadWarning]:
    """``implant_violates_margin`` naming every landmark whose margin the implant body breaks
    (its clearance below the margin: the computed clearance is never below the true one, so a
    break reported is a break); empty otherwise."""
    if result is None or plan.implant is None:
        return []
    broken = broken_margins_text(result)
    if not broken:
        return []
    out = [
        LoadWarning(
            "implant_violates_margin",
            f"plan {plan.name!r}: implant {plan.implant.name!r} ({plan.implant.size_text}) at its "
            "planned place breaks the safety margin: clearance of the implant body to " + broken,
        )
    ]
    lms = {lm.name: lm for lm in plan.landmarks}
    entered = [
        (result.names[i], float(result.clearance_mm[i]))
        for i in result.violated
        if result.clearance_mm[i] < 0.0 and _is_canal(lms.get(result.names[i]), result.names[i])
    ]
    out += [
        LoadWarning(
            CANAL_ENTRY_CODE,
            f"plan {plan.name!r}: implant {plan.implant.name!r} ({plan.implant.size_text}) enters "
            f"the canal {name!r}: its body reaches {-c:.2f} mm into it (move the apex up or "
            "choose a shorter implant)",
        )
        for name, c in entered
    ]
    return out


#: The warning code of an implant body that enters a nerve canal.
CANAL_ENTRY_CODE = "canal_entry"


def _is_canal(landmark: Landmark | None, name: str) -> bool:
    """A canal landmark, or a segmentation named as a canal or nerve."""
    if landmark is not None and landmark.kind == "canal":
        return True
    words = name.lower()
    return "canal" in words or "nerve" in words
