"""Exact signed distance to a convex solid of revolution (pure NumPy): the drill, the implant.

A solid of revolution about an axis is described by its **meridian**: the upper half
(``rho >= 0``) of its section by a plane through the axis, in coordinates ``(u, rho)`` where
``u`` is the axial coordinate measured from the solid's tip (``u <= 0`` behind it) and ``rho``
the distance from the axis. The meridian here is a chain of pieces from the back of the solid
to its tip:

- ``ray``: ``{(t, r): t <= u_end}``, a cylinder of radius ``r`` running back without end (the
  drill's shank, swept from outside the patient);
- ``segment``: from ``(u0, r0)`` to ``(u1, r1)`` (a cone, a flat face, a cylinder's side);
- ``arc``: an arc of the circle of centre ``(uc, 0)`` and radius ``a``, from the polar angle
  ``theta0`` (``0 < theta0 <= 90 deg``, measured from the axis towards ``rho``) down to the tip
  ``(uc + a, 0)`` (a round apex).

The section is the region ``u_lo <= u <= u_hi, rho <= r(u)`` under the chain (``r(u)`` the
chain's radius, concave), mirrored about the axis; it must be convex, so the solid is convex.
For a convex section symmetric about the axis, the nearest boundary point to a point with
``rho >= 0`` lies on the upper half, from inside as from outside, so the signed distance is the
2-D distance to the chain, negated inside. Because the solid is convex, that signed distance
is a convex, 1-Lipschitz function in space: :mod:`ctdrill.imaging.plan.distance` minimises it
over segments exactly with that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RAY, SEGMENT, ARC = "ray", "segment", "arc"


@dataclass(frozen=True)
class Piece:
    """One piece of a meridian chain (see the module docstring); lengths in mm.

    ``ray``: ``a = (u_end, r)``; ``segment``: ``a = (u0, r0)``, ``b = (u1, r1)`` with
    ``u0 <= u1``; ``arc``: ``a = (uc, radius)``, ``b = (cos theta0, sin theta0)``.
    """

    kind: str
    a: tuple[float, float]
    b: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Meridian:
    """A convex meridian chain, back to tip (``pieces``); see the module docstring."""

    pieces: tuple[Piece, ...]

    def __post_init__(self) -> None:
        if not self.pieces:
            raise ValueError("meridian: at least one piece is needed")
        for p in self.pieces:
            if p.kind not in (RAY, SEGMENT, ARC):
                raise ValueError(f"meridian: unknown piece kind {p.kind!r}")
            if p.kind == SEGMENT and not p.a[0] <= p.b[0]:
                raise ValueError("meridian: a segment must run towards the tip (u0 <= u1)")
            if p.kind == ARC and not (p.a[1] > 0.0 and p.b[0] >= 0.0 and p.b[1] > 0.0):
                raise ValueError("meridian: an arc needs a radius > 0 and 0 < theta0 <= 90 deg")

    @property
    def u_range(self) -> tuple[float, float]:
        """``(u_lo, u_hi)``: the section's extent along the axis (``u_lo`` may be -inf)."""
        lo, hi = np.inf, -np.inf
        for p in self.pieces:
            if p.kind == RAY:
                lo, hi = -np.inf, max(hi, p.a[0])
            elif p.kind == SEGMENT:
                lo, hi = min(lo, p.a[0]), max(hi, p.b[0])
            else:
                lo, hi = min(lo, p.a[0]), max(hi, p.a[0] + p.a[1])
        return float(lo), float(hi)

    def signed_distance_mm(self, u_mm: np.ndarray, rho_mm: np.ndarray) -> np.ndarray:
        """Exact signed distance from points ``(u, rho)`` to the solid, mm.

        Parameters
        ----------
        u_mm, rho_mm : broadcastable arrays; axial coordinate from the tip and distance from
            the axis (its sign is ignored), mm.

        Returns
        -------
        > 0 outside, 0 on the surface, minus the distance to the surface inside; the
        broadcast shape.
        """
        u = np.asarray(u_mm, dtype=np.float64)
        rho = np.abs(np.asarray(rho_mm, dtype=np.float64))
        u, rho = np.broadcast_arrays(u, rho)
        dist = np.full(u.shape, np.inf)
        # below[i]: the point lies under the piece covering its u (inside in that slice).
        below = np.zeros(u.shape, dtype=bool)
        for p in self.pieces:
            if p.kind == RAY:
                u_end, r = p.a
                d = np.hypot(np.maximum(u - u_end, 0.0), rho - r)
                below |= (u <= u_end) & (rho <= r)
            elif p.kind == SEGMENT:
                (u0, r0), (u1, r1) = p.a, p.b
                du, dr = u1 - u0, r1 - r0
                pu, pr = u - u0, rho - r0
                len2 = du * du + dr * dr
                t = np.clip((pu * du + pr * dr) / len2, 0.0, 1.0) if len2 > 0.0 else 0.0
                d = np.hypot(pu - t * du, pr - t * dr)
                if du > 0.0:  # not a vertical face: it bounds the slice u0 <= u <= u1
                    # rho <= r0 + (r1 - r0)(u - u0)/du, without the division
                    below |= (u >= u0) & (u <= u1) & (rho * du <= r0 * du + dr * pu)
            else:
                (uc, a), (c0, s0) = p.a, p.b
                rel = u - uc
                radial = np.hypot(rel, rho)
                on_arc = np.abs(radial - a)
                ends = np.minimum(np.hypot(rel - a * c0, rho - a * s0), np.hypot(rel - a, rho))
                # Polar angle <= theta0 (the point faces the arc), without atan2.
                d = np.where(rel * s0 - rho * c0 >= 0.0, on_arc, ends)
                below |= (rel >= a * c0) & (radial <= a)
            dist = np.minimum(dist, d)
        out: np.ndarray = np.where(below, -dist, dist)
        return out


def drill_meridian(radius_mm: float, tip_length_mm: float) -> Meridian:
    """The swept drill: a cylinder of radius ``R`` from far behind to ``u = -l_t``, then the
    cone of length ``l_t`` to the tip (``l_t = 0``: a flat end face)."""
    return Meridian(
        (
            Piece(RAY, (-tip_length_mm, radius_mm)),
            Piece(SEGMENT, (-tip_length_mm, radius_mm), (0.0, 0.0)),
        )
    )


def body_meridian(
    radius_mm: float, length_mm: float, apex_radius_mm: float, *, round_apex: bool
) -> Meridian:
    """An implant body (:class:`~ctdrill.imaging.plan.implants.ImplantSpec`'s shape), tip at
    ``u = 0``, platform at ``u = -length``: the platform face, the side narrowing linearly
    from ``radius`` to ``apex_radius``, then a flat apex face of ``apex_radius``, or a
    hemisphere of ``apex_radius`` whose tip is at ``u = 0``.

    A tapered side meets a hemisphere at a slight inward crease (the side slopes, the
    hemisphere starts level), which a convex solid cannot have: the round apex is then joined
    by the side's tangent to the hemisphere instead, the body's convex hull. It contains the
    body and lies within :func:`hull_excess_mm` of it (under 0.01 mm for the generic
    library), so a distance to it is never larger than the distance to the body.
    """
    back = -length_mm
    platform = Piece(SEGMENT, (back, 0.0), (back, radius_mm))
    if not round_apex:
        return Meridian(
            (
                platform,
                Piece(SEGMENT, (back, radius_mm), (0.0, apex_radius_mm)),
                Piece(SEGMENT, (0.0, apex_radius_mm), (0.0, 0.0)),
            )
        )
    centre = -apex_radius_mm
    theta0 = _tangent_angle(back - centre, radius_mm, apex_radius_mm)
    c0, s0 = float(np.cos(theta0)), float(np.sin(theta0))
    if theta0 >= np.pi / 2.0 - 1e-15:  # a parallel side meets the hemisphere level
        c0, s0 = 0.0, 1.0
    touch = (centre + apex_radius_mm * c0, apex_radius_mm * s0)
    return Meridian(
        (
            platform,
            Piece(SEGMENT, (back, radius_mm), touch),
            Piece(ARC, (centre, apex_radius_mm), (c0, s0)),
        )
    )


def _tangent_angle(du_mm: float, rho_mm: float, radius_mm: float) -> float:
    """Polar angle (rad, from the axis) of the point where the line from ``(du, rho)``
    (relative to a circle's centre on the axis, ``du < 0``) touches the circle's upper half on
    the tip's side."""
    dist = float(np.hypot(du_mm, rho_mm))
    return float(np.arctan2(rho_mm, du_mm) - np.arccos(min(radius_mm / dist, 1.0)))


def hull_excess_mm(radius_mm: float, length_mm: float, apex_radius_mm: float) -> float:
    """How far the convex hull of a round-apex body stands outside the body, mm: at most the
    gap at the side's end, ``r_hull - apex_radius`` there (0 for a parallel side)."""
    centre = -apex_radius_mm
    theta0 = _tangent_angle(-length_mm - centre, radius_mm, apex_radius_mm)
    tu, tr = centre + apex_radius_mm * np.cos(theta0), apex_radius_mm * np.sin(theta0)
    # the hull's side from (-length, radius) to (tu, tr), at u = centre
    frac = (centre + length_mm) / (tu + length_mm)
    return float(max(radius_mm + frac * (tr - radius_mm) - apex_radius_mm, 0.0))
