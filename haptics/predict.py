"""What the force law predicts for a constant push on an uploaded table: the feed at each depth,
the time to the stop, where a push is too weak to cut, and why a session may differ.

Under a constant hand force ``F`` the front yields at the model's steady feed
``v(x) = (F / S0(x) - 1) / Ke`` (:func:`ctdrill.model.cutting.steady_feed_mm_s`), so it reaches
the stop after ``t = integral dx / v(x)`` from the surface to the stop depth. Where
``S0(x) >= F`` the push is too weak to cut: the drill stalls there. Where ``S0 = 0`` (air, soft
tissue, a canal) nothing resists and the drill moves at the pace of the hand and the master's
mass, not at a model feed: those millimetres count 0 s in the prediction and are reported.
The integral runs over the table's rows subdivided :data:`SUBSTEPS` times (midpoint rule on
the linear interpolation the device uses).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.haptics.plant import COULOMB_N, KF, MASS_KG
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.renderer import CONTINUOUS_FORCE_N, THERMAL_BUDGET_N2_S
from ctdrill.model.force import MAX_FEED_MM_S, feed_at_factor_mm_s

#: Sub-steps per table row in the time integral.
SUBSTEPS = 16


@dataclass(frozen=True)
class PushPrediction:
    """The model's account of a constant push (see module docstring).

    Attributes
    ----------
    push_n : float
        Hand force, N.
    stop_depth_mm : float
    time_to_stop_s : float
        ``integral dx / v(x)`` to the stop, s; ``inf`` when the push stalls on the way.
    stall_depth_mm, stall_s0_n : float or None
        The first depth where ``S0 >= push`` (the drill holds there) and ``S0`` there.
    friction_depth_mm, friction_s0_n : float or None
        Short of a stall, the first depth where the push exceeds ``S0`` by no more than the
        master's Coulomb friction (1 N): the friction model fades to 0 at standstill, so once
        the stage stops there (after the impact's rebound, say) its static friction can hold
        it and the drill with it.
    air_mm : float
        Millimetres to the stop with ``S0 = 0`` (no model feed: crossed at the hand's pace).
    min_feed_mm_s, max_feed_mm_s : float
        Model feed range over the cut depths, mm/s (nan without any).
    capped_mm : float
        Millimetres cut where the model's feed exceeds the force law's cap (50 mm/s: thin or
        soft material): the law is held at the cap there and the master's mass, not the
        model, sets the pace.
    free_s : float
        Time to cross the air and capped stretches from rest under the push alone, the master
        an apparent mass ``Mn / Kf`` (an upper bound: it enters them moving), s.
    thermal_limit_s : float or None
        When a push above the device's continuous rating (20 N) exhausts the I^2t budget and
        the force is limited to 20 N (then the hand pushes through: the time no longer holds).
    """

    push_n: float
    stop_depth_mm: float
    time_to_stop_s: float
    stall_depth_mm: float | None
    stall_s0_n: float | None
    friction_depth_mm: float | None
    friction_s0_n: float | None
    air_mm: float
    min_feed_mm_s: float
    max_feed_mm_s: float
    capped_mm: float
    free_s: float
    thermal_limit_s: float | None

    @property
    def free_mm(self) -> float:
        """Millimetres without a model feed: air and capped stretches."""
        return self.air_mm + self.capped_mm

    @property
    def too_weak(self) -> bool:
        """The push stalls before the stop."""
        return self.stall_depth_mm is not None

    def reasons(self) -> list[str]:
        """What may make a session at this push leave the model's schedule (empty: nothing)."""
        out = []
        if self.stall_depth_mm is not None:
            out.append(
                f"push {self.push_n:g} N too weak to cut at {self.stall_depth_mm:.2f} mm "
                f"(static cutting force S0 = {self.stall_s0_n:.2f} N): the drill holds there"
            )
        if self.friction_depth_mm is not None:
            out.append(
                f"from {self.friction_depth_mm:.2f} mm the push exceeds S0 "
                f"({self.friction_s0_n:.2f} N) by no more than the master's {COULOMB_N:g} N "
                "static friction, which holds the drill once it stops there"
            )
        if self.free_mm > 0.0:
            out.append(
                f"{self.free_mm:.2f} mm without a model feed (no bone, or thin bone where the "
                f"feed exceeds the law's {MAX_FEED_MM_S:g} mm/s cap) crossed at the pace of the "
                f"master's mass: up to {1e3 * self.free_s:.0f} ms"
            )
        if self.thermal_limit_s is not None and self.thermal_limit_s < self.time_to_stop_s:
            out.append(
                f"above the {CONTINUOUS_FORCE_N:g} N continuous rating the device limits the "
                f"force after {self.thermal_limit_s:.1f} s (I2t budget)"
            )
        return out


def predict_push(table: ProfileTable, push_n: float) -> PushPrediction:
    """The model's schedule of a constant ``push_n`` from the surface to the table's stop."""
    stop = float(table.stop_depth_mm)
    step = float(table.depth_step_mm)
    s0 = table.s0_n.astype(float)
    ke = float(table.ke_per_mm_s)
    n = max(1, math.ceil(stop / step * SUBSTEPS))
    edges = np.linspace(0.0, stop, n + 1)
    mids = 0.5 * (edges[:-1] + edges[1:])
    dx = np.diff(edges)
    rows = np.arange(s0.size) * step
    s0_mid = np.interp(mids, rows, s0, right=0.0)
    s0_edge = np.interp(edges[:-1], rows, s0, right=0.0)
    stall_depth = stall_s0 = None
    if push_n <= 0.0:  # no push: nothing moves
        stall_depth, stall_s0 = 0.0, float(s0_edge[0]) if s0_edge.size else 0.0
    elif stop > 0.0:
        stall_depth, stall_s0 = _first_at_least(edges, mids, s0_edge, s0_mid, push_n)
    friction_depth, friction_s0 = _first_at_least(edges, mids, s0_edge, s0_mid, push_n - COULOMB_N)
    cut = s0_mid > 0.0
    air_mm = float(dx[~cut].sum())
    feeds = np.full(mids.shape, np.inf)
    if ke > 0.0:
        with np.errstate(divide="ignore"):
            feeds[cut] = feed_at_factor_mm_s(push_n / s0_mid[cut], ke)
    if stall_depth is not None:
        time_s = math.inf
    else:
        time_s = float(np.sum(dx[cut] / feeds[cut])) if np.any(cut) else 0.0
    cut_feeds = feeds[cut & (feeds > 0.0)]
    thermal = None
    if push_n > CONTINUOUS_FORCE_N:
        thermal = THERMAL_BUDGET_N2_S / (push_n**2 - CONTINUOUS_FORCE_N**2)
    return PushPrediction(
        push_n=push_n,
        stop_depth_mm=stop,
        time_to_stop_s=time_s,
        stall_depth_mm=stall_depth,
        stall_s0_n=stall_s0,
        friction_depth_mm=friction_depth if stall_depth is None else None,
        friction_s0_n=friction_s0 if stall_depth is None else None,
        air_mm=air_mm,
        min_feed_mm_s=float(cut_feeds.min()) if cut_feeds.size else math.nan,
        max_feed_mm_s=float(cut_feeds.max()) if cut_feeds.size else math.nan,
        capped_mm=float(dx[cut & (feeds > MAX_FEED_MM_S)].sum()),
        free_s=_free_time_s(dx, ~cut | (feeds > MAX_FEED_MM_S), push_n),
        thermal_limit_s=thermal,
    )


def _free_time_s(dx: np.ndarray, free: np.ndarray, push_n: float) -> float:
    """Each contiguous free stretch crossed from rest at ``Kf F / Mn``, summed, s."""
    if push_n <= 0.0 or not np.any(free):
        return 0.0 if not np.any(free) else math.inf
    accel_mm_s2 = KF * push_n / MASS_KG * 1e3
    total = 0.0
    run = 0.0
    for length, is_free in zip(dx.tolist(), free.tolist(), strict=True):
        if is_free:
            run += length
        elif run > 0.0:
            total += math.sqrt(2.0 * run / accel_mm_s2)
            run = 0.0
    if run > 0.0:
        total += math.sqrt(2.0 * run / accel_mm_s2)
    return total


def _first_at_least(
    edges: np.ndarray, mids: np.ndarray, s0_edge: np.ndarray, s0_mid: np.ndarray, force_n: float
) -> tuple[float | None, float | None]:
    """The first depth (sub-step edge or midpoint) where ``0 < S0 >= force_n`` and ``S0`` there."""
    hit_edge = (s0_edge >= force_n) & (s0_edge > 0.0)
    hit = hit_edge | (s0_mid >= force_n) & (s0_mid > 0.0)
    if not np.any(hit):
        return None, None
    i = int(np.argmax(hit))
    if hit_edge[i]:
        return float(edges[i]), float(s0_edge[i])
    return float(mids[i]), float(s0_mid[i])
