"""Dental implants: the body's shape, the library of sizes, and where a plan places one.

An implant (:class:`ImplantSpec`) is a solid of revolution about the trajectory's axis:

- the body runs from the **platform** (``s = 0``, diameter ``diameter_mm``) to the **apex**
  (``s = length_mm``); its side wall narrows linearly to ``apex_diameter_mm`` (equal to
  ``diameter_mm``: a cylinder; smaller: a tapered body);
- ``apex = "flat"``: the body ends in a flat face of diameter ``apex_diameter_mm`` at
  ``s = length_mm``;
- ``apex = "round"``: the body ends in a hemisphere of radius ``apex_diameter_mm / 2`` whose
  tip is at ``s = length_mm`` (the side wall then narrows from ``s = 0`` to
  ``s = length_mm - apex_diameter_mm / 2``); the total length stays ``length_mm``.

Placement (:func:`implant_placement`): the apex sits at the planned target and the platform
``length_mm`` back along the axis (towards the entry), as a planner places an implant on a
planned osteotomy. The drill's stop is not the implant's: the warnings of
:func:`implant_warnings` say when they disagree.

The library (``ctdrill-implants/1``, :func:`load_implant_library`): generic sizes in
``assets/implants/generic.json``; a user file of the same format extends it, an entry with a
library name replacing it::

    {"format": "ctdrill-implants/1",
     "implants": [{"name": "tapered 4.1 x 10", "diameter_mm": 4.1, "length_mm": 10.0,
                   "apex_diameter_mm": 2.9, "apex": "round",
                   "drills": [{"diameter_mm": 2.0, "tip_length_mm": 0.6},
                              {"diameter_mm": 2.8, "tip_length_mm": 0.8},
                              {"diameter_mm": 3.5, "tip_length_mm": 1.0}]}]}

``drills`` (optional) is the implant's **drilling protocol**: the drills in drilling order, the
last one sized for the implant, each with its tip length (how far it cuts beyond the depth its
full diameter reaches); :mod:`ctdrill.imaging.plan.protocol` uses it (or the generic rule).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.drill_spec import (
    POINT_ANGLE_DEG,
    POINT_ANGLE_RANGE_DEG,
    PROTOCOL_DRILL_KEYS,
    PROTOCOL_OPTIONAL_KEYS,
    DrillSpec,
    positive_finite,
    protocol_error,
    protocol_json,
)
from ctdrill.resources import asset
from ctdrill.safeio import load_json

IMPLANTS_FORMAT = "ctdrill-implants/1"
#: The library shipped with ctdrill (generic sizes, no brand).
DEFAULT_LIBRARY: Path = asset("implants", "generic.json")
APEX_SHAPES = ("flat", "round")
#: Largest accepted implant diameter and length, mm: dental implants are 3-7 mm wide and
#: 6-18 mm long; beyond these a value is a unit error, refused.
MAX_IMPLANT_DIAMETER_MM = 10.0
MAX_IMPLANT_LENGTH_MM = 30.0
#: Longest implant name accepted (characters).
MAX_NAME_CHARS = 200
#: Most implants a library file may list.
MAX_LIBRARY_IMPLANTS = 10_000
#: The clinical minimum distance between two implants, mm (DESIGN.md section 5): its one owner.
MIN_IMPLANT_DISTANCE_MM = 3.0
#: Keys of an implant object (plan files and library files), all required.
IMPLANT_KEYS = ("name", "diameter_mm", "length_mm", "apex_diameter_mm", "apex")
#: The optional key of an implant object: its drilling protocol
#: (:mod:`ctdrill.imaging.plan.protocol`).
PROTOCOL_KEY = "drills"


class ImplantInputError(ImagingInputError):
    """A bad implant or implant library; the message names the file and field."""


def spec_error(
    name: object, diameter_mm: object, length_mm: object, apex_diameter_mm: object, apex: object
) -> tuple[str, str] | None:
    """``(field, what is wrong)`` for an invalid implant, or None when it is valid."""
    if not isinstance(name, str) or not name.strip() or len(name) > MAX_NAME_CHARS:
        return "name", f"must be a non-empty string of at most {MAX_NAME_CHARS} characters"
    for key, value, top in (
        ("diameter_mm", diameter_mm, MAX_IMPLANT_DIAMETER_MM),
        ("length_mm", length_mm, MAX_IMPLANT_LENGTH_MM),
        ("apex_diameter_mm", apex_diameter_mm, MAX_IMPLANT_DIAMETER_MM),
    ):
        if not positive_finite(value):
            return key, "must be a positive number (mm)"
        if not float(value) <= top:  # type: ignore[arg-type]
            return key, f"must be at most {top:g} mm (check the units)"
    if not float(apex_diameter_mm) <= float(diameter_mm):  # type: ignore[arg-type]
        return "apex_diameter_mm", "must be at most diameter_mm (a body narrows to its apex)"
    if apex not in APEX_SHAPES:
        return "apex", 'must be "flat" or "round"'
    if apex == "round" and not float(length_mm) > float(apex_diameter_mm) / 2.0:  # type: ignore[arg-type]
        return "length_mm", "must exceed apex_diameter_mm / 2 (the round apex's radius)"
    return None


@dataclass(frozen=True)
class ImplantSpec:
    """One implant body (mm); see the module docstring for the shape.

    Attributes
    ----------
    name : a label (library entries are unique by name).
    diameter_mm : platform (and widest) diameter.
    length_mm : platform to apex tip.
    apex_diameter_mm : diameter where the side wall ends (<= ``diameter_mm``).
    apex : ``"flat"`` or ``"round"``.
    drills : its drilling protocol in drilling order (the last drill sized for the implant),
        each a :class:`DrillSpec` with its diameter and tip length; empty when none is known
        (:func:`ctdrill.imaging.plan.protocol.protocol_drills` then gives the generic one).
    """

    name: str
    diameter_mm: float
    length_mm: float
    apex_diameter_mm: float
    apex: str = "flat"
    drills: tuple[DrillSpec, ...] = ()

    def __post_init__(self) -> None:
        problem = spec_error(
            self.name, self.diameter_mm, self.length_mm, self.apex_diameter_mm, self.apex
        )
        if problem is not None:
            raise ImplantInputError(
                f"implant {self.name!r}: {problem[0]} {problem[1]}, got "
                f"{getattr(self, problem[0])!r}"
            )
        for key in ("diameter_mm", "length_mm", "apex_diameter_mm"):
            object.__setattr__(self, key, float(getattr(self, key)))
        object.__setattr__(self, "drills", tuple(self.drills))
        bad = protocol_error(self.drills, max_diameter_mm=MAX_IMPLANT_DIAMETER_MM)
        if bad is not None:
            raise ImplantInputError(f"implant {self.name!r}: {bad}")

    @property
    def size_text(self) -> str:
        """Diameter x length as implant lists print it: ``4.1 x 10 mm``."""
        return f"{self.diameter_mm:g} x {self.length_mm:g} mm"

    @property
    def radius_mm(self) -> float:
        """Platform radius, mm (the widest part of the body)."""
        return self.diameter_mm / 2.0

    def to_json(self) -> dict[str, Any]:
        """The implant object of plan and library files (``drills`` only when it has a
        protocol: each drill's ``diameter_mm`` and ``tip_length_mm``)."""
        out: dict[str, Any] = {
            "name": self.name,
            "diameter_mm": self.diameter_mm,
            "length_mm": self.length_mm,
            "apex_diameter_mm": self.apex_diameter_mm,
            "apex": self.apex,
        }
        if self.drills:
            out[PROTOCOL_KEY] = protocol_json(self.drills)
        return out

    def profile_mm(self, n: int = 16) -> tuple[np.ndarray, np.ndarray]:
        """The body's outline: radius ``r_mm`` at distance ``s_mm`` from the platform.

        Parameters
        ----------
        n : points on the round apex's quarter circle (>= 2); a flat apex needs none.

        Returns
        -------
        s_mm, r_mm : (M,) float64, ``s`` non-decreasing from 0 (platform, ``r = radius``) to
            ``length_mm`` (apex, ``r = 0``). Straight lines between the points are the exact
            outline for a flat apex; for a round one the apex arc is sampled at ``n`` points.
        """
        r0, ra, length = self.radius_mm, self.apex_diameter_mm / 2.0, self.length_mm
        if self.apex == "flat":
            return np.array([0.0, length, length]), np.array([r0, ra, 0.0])
        if n < 2:
            raise ValueError(f"n must be >= 2, got {n}")
        centre = length - ra
        theta = np.linspace(0.0, np.pi / 2.0, n)
        s = np.concatenate([[0.0], centre + ra * np.sin(theta)])
        r = np.concatenate([[r0], ra * np.cos(theta)])
        s[-1], r[-1] = length, 0.0
        return s, r

    def radius_at_mm(self, s_mm: float) -> float:
        """Body radius at ``s_mm`` from the platform (0 outside ``[0, length_mm]``), mm."""
        r0, ra, length = self.radius_mm, self.apex_diameter_mm / 2.0, self.length_mm
        if not 0.0 <= s_mm <= length:
            return 0.0
        wall = length if self.apex == "flat" else length - ra
        if s_mm <= wall:
            return r0 + (ra - r0) * (s_mm / wall if wall > 0.0 else 1.0)
        return math.sqrt(max(ra * ra - (s_mm - wall) ** 2, 0.0))


def implant_from_json(raw: object, *, where: str, source: str) -> ImplantSpec:
    """An :class:`ImplantSpec` from its JSON object, refused naming ``source: where.field``.

    Every key of :data:`IMPLANT_KEYS` is required (a plan carries its implant in full);
    ``drills`` (:data:`PROTOCOL_KEY`, the drilling protocol) is optional.
    """
    if not isinstance(raw, dict):
        raise ImplantInputError(f"{source}: {where} must be an implant object, got {raw!r}")
    known = (*IMPLANT_KEYS, PROTOCOL_KEY)
    extra = sorted(set(raw) - set(known))
    if extra:
        raise ImplantInputError(
            f"{source}: {where}.{extra[0]} is not a known field (known: {', '.join(known)})"
        )
    missing = [k for k in IMPLANT_KEYS if k not in raw]
    if missing:
        raise ImplantInputError(f"{source}: {where}.{missing[0]} is missing; add it")
    problem = spec_error(*(raw[k] for k in IMPLANT_KEYS))
    if problem is not None:
        raise ImplantInputError(
            f"{source}: {where}.{problem[0]} {problem[1]}, got {raw[problem[0]]!r}"
        )
    drills = (
        protocol_from_json(raw[PROTOCOL_KEY], where=f"{where}.{PROTOCOL_KEY}", source=source)
        if PROTOCOL_KEY in raw
        else ()
    )
    return ImplantSpec(**{k: raw[k] for k in IMPLANT_KEYS}, drills=drills)


def protocol_from_json(raw: object, *, where: str, source: str) -> tuple[DrillSpec, ...]:
    """A drilling protocol (a non-empty list of ``{"diameter_mm", "tip_length_mm"}`` in
    drilling order, diameters increasing), refused naming ``source: where[i].field``."""
    if not isinstance(raw, list) or not raw:
        raise ImplantInputError(
            f"{source}: {where} must be a non-empty list of drills "
            '({"diameter_mm": ..., "tip_length_mm": ...}) in drilling order'
        )
    out = []
    for i, item in enumerate(raw):
        fi = f"{where}[{i}]"
        if not isinstance(item, dict):
            raise ImplantInputError(f"{source}: {fi} must be a drill object, got {item!r}")
        known = (*PROTOCOL_DRILL_KEYS, *PROTOCOL_OPTIONAL_KEYS)
        extra = sorted(set(item) - set(known))
        if extra:
            raise ImplantInputError(
                f"{source}: {fi}.{extra[0]} is not a known field (known: {', '.join(known)})"
            )
        for key in known:
            if key not in item:
                if key in PROTOCOL_DRILL_KEYS:
                    raise ImplantInputError(f"{source}: {fi}.{key} is missing; add it")
                continue
            if not positive_finite(item[key]):
                raise ImplantInputError(
                    f"{source}: {fi}.{key} must be a positive number, got {item[key]!r}"
                )
        angle = float(item.get("point_angle_deg", POINT_ANGLE_DEG))
        lo, hi = POINT_ANGLE_RANGE_DEG
        if not lo < angle < hi:
            raise ImplantInputError(
                f"{source}: {fi}.point_angle_deg must be between {lo:g} and {hi:g} deg, "
                f"got {angle:g}"
            )
        tip = float(item["tip_length_mm"]) if "tip_length_mm" in item else math.nan
        out.append(DrillSpec(float(item["diameter_mm"]), tip, point_angle_deg=angle))
    drills = tuple(out)
    problem = protocol_error(drills, max_diameter_mm=MAX_IMPLANT_DIAMETER_MM)
    if problem is not None:
        raise ImplantInputError(f"{source}: {where}{problem.removeprefix('drills')}")
    return drills


def read_library_file(path: str | os.PathLike[str]) -> tuple[ImplantSpec, ...]:
    """The implants of one ``ctdrill-implants/1`` file, validated (names unique)."""
    p = Path(path)
    doc = load_json(p, what="implant library", error=ImplantInputError)
    src = p.name
    if not isinstance(doc, dict):
        raise ImplantInputError(f"{src}: (top level) must be a JSON object")
    extra = sorted(set(doc) - {"format", "implants", "description"})
    if extra:
        raise ImplantInputError(
            f"{src}: {extra[0]} is not a known field (known: description, format, implants)"
        )
    if doc.get("format") != IMPLANTS_FORMAT:
        raise ImplantInputError(
            f'{src}: format must be "{IMPLANTS_FORMAT}", got {doc.get("format")!r}'
        )
    items = doc.get("implants")
    if not isinstance(items, list) or not items:
        raise ImplantInputError(f"{src}: implants must be a non-empty list of implant objects")
    if len(items) > MAX_LIBRARY_IMPLANTS:
        raise ImplantInputError(
            f"{src}: implants lists {len(items)} implants, more than {MAX_LIBRARY_IMPLANTS}"
        )
    out: dict[str, ImplantSpec] = {}
    for i, raw in enumerate(items):
        spec = implant_from_json(raw, where=f"implants[{i}]", source=src)
        if spec.name in out:
            raise ImplantInputError(
                f"{src}: implants[{i}].name {spec.name!r} is listed twice; names are unique"
            )
        out[spec.name] = spec
    return tuple(out.values())


def load_implant_library(path: str | os.PathLike[str] | None = None) -> tuple[ImplantSpec, ...]:
    """The implant library: ctdrill's generic sizes, extended by the user's file ``path``.

    An implant of ``path`` named as a library one replaces it (in place); the others follow
    the library's, in the file's order.

    Raises
    ------
    ImplantInputError
        A file that is missing, not ``ctdrill-implants/1`` or holds an invalid implant (the
        message names the file and the field, e.g. ``mine.json: implants[2].length_mm ...``).
    """
    merged = {s.name: s for s in read_library_file(DEFAULT_LIBRARY)}
    if path is not None:
        for spec in read_library_file(path):
            merged[spec.name] = spec
    return tuple(merged.values())


@dataclass(frozen=True, eq=False)
class ImplantPlacement:
    """An implant placed on a trajectory, LPS mm.

    Attributes
    ----------
    spec : the implant.
    platform_lps, apex_lps : (3,) the platform centre and the apex tip.
    axis_lps : (3,) unit vector platform -> apex (the trajectory's entry -> target).
    platform_depth_mm, apex_depth_mm : their depths from the entry along the trajectory
        (the apex's is the planned depth; the platform's is negative above the entry).
    """

    spec: ImplantSpec
    platform_lps: np.ndarray
    apex_lps: np.ndarray
    axis_lps: np.ndarray
    platform_depth_mm: float
    apex_depth_mm: float

    def to_json(self) -> dict[str, Any]:
        """The placement for summaries: the spec's keys, ``platform_lps``, ``apex_lps``,
        ``axis_lps``, ``platform_depth_mm``, ``apex_depth_mm``."""
        return {
            **self.spec.to_json(),
            "platform_lps": self.platform_lps.tolist(),
            "apex_lps": self.apex_lps.tolist(),
            "axis_lps": self.axis_lps.tolist(),
            "platform_depth_mm": self.platform_depth_mm,
            "apex_depth_mm": self.apex_depth_mm,
        }

    def point_at_mm(self, s_mm: float) -> np.ndarray:
        """(3,) LPS point on the axis ``s_mm`` from the platform towards the apex."""
        out: np.ndarray = self.platform_lps + s_mm * self.axis_lps
        return out


class PlacedTrajectory(Protocol):
    """What :func:`implant_placement` reads of a trajectory (a
    :class:`~ctdrill.imaging.plan.types.Plan` is one; the plan types sit above this module)."""

    @property
    def implant(self) -> ImplantSpec | None: ...

    @property
    def planned_target_lps(self) -> np.ndarray: ...

    @property
    def direction(self) -> np.ndarray: ...

    @property
    def planned_depth_mm(self) -> float: ...

    @property
    def overdrill_mm(self) -> float: ...


def implant_placement(plan: PlacedTrajectory) -> ImplantPlacement | None:
    """Where ``plan``'s implant sits: apex at the plan's target
    (:attr:`~ctdrill.imaging.plan.types.Plan.planned_target_lps`; a drill's view,
    ``plan.drilled(k)``, drills beyond it), platform ``length_mm`` back along the axis; None
    when the plan has no implant."""
    spec = plan.implant
    if spec is None:
        return None
    axis = np.array(plan.direction, dtype=np.float64)
    apex = np.array(plan.planned_target_lps, dtype=np.float64)
    platform = apex - spec.length_mm * axis
    for arr in (axis, apex, platform):
        arr.flags.writeable = False
    depth = plan.planned_depth_mm - plan.overdrill_mm
    return ImplantPlacement(spec, platform, apex, axis, depth - spec.length_mm, depth)
