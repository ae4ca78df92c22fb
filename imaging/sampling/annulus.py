"""The cutting lip of a drill that follows a narrower one: only the part outside the hole cuts.

A drill sequence (pilot 2.0 mm, then 2.8, 3.5 ...) drills every drill along the same axis.
Drill ``j`` leaves a hole: its solid (DESIGN.md section 2) swept down to the depth ``d_j`` its
tip actually reached (its stop depth): the cylinder of radius ``r_j`` above the cone of length
``l_j`` ending at the tip point. In the meridian plane, a point at radius ``r`` from the axis
and depth ``xi`` lies in that hole when ``r < r_j`` and ``xi < d_j - (l_j / r_j) r``.

The next drill's lip element at radius ``r`` sits at ``xi = x - (l_t / R) r`` (tip depth ``x``,
radius ``R``, tip length ``l_t``). It is in hole ``j`` when ``r < r_j`` and
``r (b_j - a) < d_j - x`` with ``a = l_t / R`` and ``b_j = l_j / r_j``: for every depth an
interval of ``r`` (``[0, min(r_j, (d_j - x)/(b_j - a)))`` if ``b_j > a``; ``[0, r_j)`` down to
``d_j`` (at ``x = d_j`` the lip lies on the hole's cone: nothing new is cut yet) and nothing
below if ``b_j = a``, the usual case of equal point angles;
``(max(0, (x - d_j)/(a - b_j)), r_j)`` if ``b_j < a``). Several holes give a union of intervals;
what is left of ``[0, R]`` is the **cut set** ``C(x)``, never shorter than ``R - max r_j > 0``
(diameters strictly increase).

The lip integral (DESIGN.md 1.4) ``(1/R) int_0^R mean_theta f dr`` becomes
``(1/R) int_C(x) mean_theta f dr``. :func:`annulus_rings` places the rings on ``C(x)`` itself:
the midpoint rule in the arc-length ``s`` of ``C(x)`` (``n`` equal bins of ``|C(x)|``), each
ring weighted ``|C(x)| / (n R)``. No ring lies in the hole and no cut material is left out:
the quadrature is exact for material uniform along the lip (a slab the lip lies wholly in: the
force is then the full-lip force times ``|C| / R``) and otherwise has the midpoint rule's
error on each cut interval, as the full lip has on ``[0, R]``. With no hole the rings are the
full lip's (``(i + 1/2) R / n``, weight ``1 / n``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.types import DrillSpec


class HoleInputError(ImagingInputError):
    """A hole that no drill could have left (non-finite or non-positive sizes)."""


@dataclass(frozen=True)
class Hole:
    """The hole an earlier drill of a sequence left along the same axis.

    Attributes
    ----------
    radius_mm : the drill's radius, mm (> 0).
    tip_length_mm : the drill's cone length, mm (>= 0; 0 is a flat bottom).
    depth_mm : the depth its tip reached from the entry point, mm (its stop depth).
    """

    radius_mm: float
    tip_length_mm: float
    depth_mm: float

    def __post_init__(self) -> None:
        for name, low_ok in (("radius_mm", False), ("tip_length_mm", True), ("depth_mm", True)):
            v = float(getattr(self, name))
            if not np.isfinite(v) or v < 0.0 or (v == 0.0 and not low_ok):
                raise HoleInputError(f"hole {name}: must be a finite length, got {v!r}")

    @classmethod
    def of(cls, drill: DrillSpec, depth_mm: float) -> Hole:
        """The hole ``drill`` leaves when its tip reaches ``depth_mm``."""
        return cls(drill.radius_mm, drill.tip_length_mm, float(depth_mm))


def hole_intervals(
    radius_mm: float, tip_length_mm: float, depth_mm: np.ndarray, holes: Sequence[Hole]
) -> tuple[np.ndarray, np.ndarray]:
    """Where each hole holds the lip: ``lo, hi`` of shape (D, H), the radii ``[lo, hi)`` of
    the lip (radius ``radius_mm``, tip ``tip_length_mm``, tip at ``depth_mm``) inside hole ``h``
    (``lo == hi`` where none is), clipped to ``[0, radius_mm]``."""
    depth = np.asarray(depth_mm, dtype=np.float64).reshape(-1)
    a = tip_length_mm / radius_mm
    lo = np.zeros((depth.size, len(holes)))
    hi = np.zeros((depth.size, len(holes)))
    for h, hole in enumerate(holes):
        r_h = min(hole.radius_mm, radius_mm)
        b = hole.tip_length_mm / hole.radius_mm
        gap = hole.depth_mm - depth  # > 0: the tip is above the hole's tip
        if b > a:
            hi[:, h] = np.clip(gap / (b - a), 0.0, r_h)
        elif b == a:
            hi[:, h] = np.where(gap >= 0.0, r_h, 0.0)
        else:
            lo[:, h] = np.clip(-gap / (a - b), 0.0, r_h)
            hi[:, h] = r_h
    return lo, hi


def annulus_rings(
    radius_mm: float,
    tip_length_mm: float,
    depth_mm: np.ndarray,
    holes: Sequence[Hole],
    n_rings: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Ring radii and weights on the cut set ``C(x)`` of the lip at each tip depth.

    Parameters
    ----------
    radius_mm, tip_length_mm : the drill's radius (> 0) and cone length (>= 0), mm.
    depth_mm : (D,) tip depths, mm.
    holes : the holes of the earlier drills (any order; they may overlap).
    n_rings : rings per depth (>= 1).

    Returns
    -------
    radii_mm, weights : (D, n_rings) each. Ring ``i`` sits at arc length
        ``(i + 1/2) |C| / n`` along ``C(x)`` (read from the axis outwards) and weighs
        ``|C| / (n R)``: the weights of a depth sum to the cut share ``|C(x)| / R`` of the lip.
    """
    depth = np.asarray(depth_mm, dtype=np.float64).reshape(-1)
    lo, hi = hole_intervals(radius_mm, tip_length_mm, depth, holes)
    n_d = depth.size
    edges = np.sort(
        np.concatenate([np.zeros((n_d, 1)), lo, hi, np.full((n_d, 1), radius_mm)], axis=1), axis=1
    )  # (D, S + 1): every interval end, so each segment is wholly in or out of the holes
    seg = np.diff(edges, axis=1)  # (D, S)
    mid = edges[:, :-1] + 0.5 * seg
    covered = np.any(
        (mid[:, :, None] >= lo[:, None, :]) & (mid[:, :, None] < hi[:, None, :]), axis=2
    )
    cut = np.where(covered, 0.0, seg)
    cum = np.concatenate([np.zeros((n_d, 1)), np.cumsum(cut, axis=1)], axis=1)  # (D, S + 1)
    total = cum[:, -1]  # |C(x)|
    s = (np.arange(n_rings, dtype=np.float64) + 0.5) / n_rings * total[:, None]  # (D, n)
    # the segment holding arc length s: the last with cum[k] <= s < cum[k + 1] (an uncut
    # segment adds nothing to cum, so the one found is cut)
    k = np.sum(cum[:, None, 1:] <= s[:, :, None], axis=2)
    k = np.minimum(k, seg.shape[1] - 1)
    rows = np.arange(n_d)[:, None]
    radii = edges[rows, k] + (s - cum[rows, k])
    weights = np.repeat((total / (n_rings * radius_mm))[:, None], n_rings, axis=1)
    return radii, weights


def holes_on_grid(holes: tuple[Hole, ...], depth_mm: np.ndarray) -> tuple[Hole, ...]:
    """``holes`` with each depth rounded **up** to the profile's depth grid.

    The profile is linear between grid depths (``force_n``, the device table, force.csv). At
    the bottom of an earlier hole the force jumps (equal point angles) from the annulus to the
    full lip; sampled at the true depth, the grid depth just below the bottom would still be
    annulus and the one just above it full, so the interpolated force would start rising up to
    one step *inside* the hole. Placed at the next grid depth, the hole holds exactly at every
    depth down to its true bottom (a drill stopping where the one before it stopped feels only
    the annulus), and the full lip engages late by less than two steps (a larger hole only
    removes material: no force is ever added). A depth within 1e-9 mm of a grid depth is that
    grid depth; one past the grid's end is kept.
    """
    if not holes:
        return holes
    tol = 1e-9
    out = []
    for hole in holes:
        k = int(np.searchsorted(depth_mm, hole.depth_mm - tol, side="left"))
        snapped = hole.depth_mm if k >= depth_mm.size else float(depth_mm[k])
        out.append(replace(hole, depth_mm=max(snapped, hole.depth_mm)))
    return tuple(out)
