"""Rehearsal readouts that explain themselves (headless: the panel, the summary and the CLI).

Three forces, kept apart:

* the **hand** force: what the device's reaction-force observer reads of the operator
  (telemetry ``force_est_n``; the simulator's hand is the set push);
* the **device** force: what the device renders against the advance (``force_cmd_n``), named by
  what it is: the cut (``cutting``), the stop's wall (``wall``), the material holding a push
  too weak to cut it (``holding``), nothing to cut (``free``), or no force (``off``);
* the **model's** cutting force at the drill depth: the static ``S0`` there (the force a push
  must exceed to cut at all) and ``S0 (1 + Ke v)`` at the plan's feed (what ``export`` shows).

And the time to the stop at a constant push: the model's schedule
(:func:`ctdrill.haptics.predict.predict_push`) against the session's, agreeing within
:data:`TIME_TOLERANCE_REL` + :data:`TIME_TOLERANCE_S` or saying why not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ctdrill.haptics.plant import COULOMB_N
from ctdrill.haptics.predict import PushPrediction, predict_push
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.renderer import CONTINUOUS_FORCE_N, PEAK_FORCE_N, WALL_HOLD_MM
from ctdrill.model.cutting import steady_feed_mm_s
from ctdrill.model.force import feed_factor_scalar

#: A session's time to the stop agrees with the model's within this fraction plus
#: :data:`TIME_TOLERANCE_S`: the start (the coupling spring compressed to ``F / k`` through a
#: quarter period of the 24 Hz coupled mode, the front's relaxation ``S0 Ke / k``) delays it
#: by 10-40 ms on slabs (tests/app/test_readout.py).
TIME_TOLERANCE_REL = 0.02
TIME_TOLERANCE_S = 0.02
#: The master is beyond the front (in contact) by more than this, mm (one encoder count).
CONTACT_MM = 1e-4
#: Below this measured drill feed the drill counts as holding, mm/s.
STILL_MM_S = 0.01


def push_of(operator_spec: str) -> float | None:
    """The constant hand force of a ``push:N`` operator, N (None for feed and script)."""
    kind, _, value = operator_spec.partition(":")
    if kind != "push":
        return None
    try:
        push = float(value)
    except ValueError:
        return None
    return push if math.isfinite(push) else None


def s0_at(table: ProfileTable, depth_mm: float) -> float:
    """``S0`` at ``depth_mm`` as the device interpolates it (0 outside the table), N."""
    rows = np.arange(table.n_steps) * float(table.depth_step_mm)
    return float(np.interp(depth_mm, rows, table.s0_n.astype(float), left=0.0, right=0.0))


def harmonics_at(table: ProfileTable, depth_mm: float) -> tuple[float, float]:
    """``(S1, S2)`` at ``depth_mm`` as the device interpolates them (0 outside the table), N."""
    rows = np.arange(table.n_steps) * float(table.depth_step_mm)
    return (
        float(np.interp(depth_mm, rows, table.s1_n.astype(float), left=0.0, right=0.0)),
        float(np.interp(depth_mm, rows, table.s2_n.astype(float), left=0.0, right=0.0)),
    )


@dataclass(frozen=True)
class LiveReadout:
    """What the panel shows for one telemetry sample."""

    hand_n: float | None
    device_n: float
    kind: str  # cutting | wall | holding | free | off
    s0_n: float
    plan_force_n: float
    status: str


def live_readout(
    table: ProfileTable,
    *,
    state: str,
    master_mm: float,
    drill_mm: float,
    force_n: float,
    hand_n: float | None,
    push_n: float | None,
    plan_feed_mm_s: float,
    drill_feed_mm_s: float | None = None,
) -> LiveReadout:
    """Name the device's force and say what the push does at the drill depth.

    ``push_n`` is the simulated hand's set force (None on a real device: the hand estimate
    ``hand_n`` stands in for it); ``drill_feed_mm_s`` the drill's measured feed over the last
    moments (None: unknown). A push at most ``S0`` is too weak to cut; one that exceeds ``S0``
    by less than the master's Coulomb friction (1 N) may be held by it: then, if the drill is
    not advancing, that is said too.
    """
    s0 = s0_at(table, drill_mm)
    ke = float(table.ke_per_mm_s)
    plan_force = s0 * feed_factor_scalar(plan_feed_mm_s, ke)
    push = push_n if push_n is not None else hand_n
    if state in ("idle", "safe"):
        kind, status = "off", f"no force: the device is {state}"
    elif state == "stopped":
        kind = "wall"
        status = (
            f"at the stop: the wall holds {force_n:.1f} N; the hand is "
            f"{max(master_mm - drill_mm, 0.0):.2f} mm past the stopped drill"
        )
    elif (
        push is not None
        and push <= COULOMB_N
        and drill_feed_mm_s is not None
        and drill_feed_mm_s < STILL_MM_S
    ):
        kind = "holding"
        status = (
            f"push too weak to move the master: {push:.1f} N against its {COULOMB_N:g} N "
            "Coulomb friction; nothing moves"
        )
    elif master_mm <= drill_mm + CONTACT_MM or s0 <= 0.0:
        kind = "free"
        status = "nothing to cut here (S0 = 0)" if s0 <= 0.0 else "in the hole: no contact"
    elif push is not None and push <= s0:
        kind = "holding"
        status = (
            f"push too weak to cut: {push:.1f} N against the static cutting force "
            f"S0 = {s0:.1f} N here; the drill holds (push harder than {s0:.1f} N to cut)"
        )
    elif (
        push is not None
        and push <= s0 + COULOMB_N
        and drill_feed_mm_s is not None
        and drill_feed_mm_s < STILL_MM_S
    ):
        kind = "holding"
        status = (
            f"push too weak to cut: {push:.1f} N is {push - s0:.1f} N over S0 = {s0:.1f} N "
            f"here, within the master's {COULOMB_N:g} N friction; the drill holds"
        )
    else:
        kind = "cutting"
        if push is None or ke <= 0.0:
            status = "cutting"
        else:
            feed = steady_feed_mm_s(push, s0, ke)
            status = f"cutting: the model's feed under {push:.1f} N here is {feed:.2f} mm/s"
    return LiveReadout(hand_n, force_n, kind, s0, plan_force, status)


#: The force gauge's three named forces: the hand, the device's cut, the stop's wall.
GAUGE_FORCES = ("hand", "cutting", "wall")


def gauge_forces(r: LiveReadout, push_n: float | None = None) -> dict[str, float]:
    """:data:`GAUGE_FORCES` of a readout, N: the hand (the device's reading, else the set
    push), the device force as the cut (``cutting`` and ``holding``: the material resists) or
    as the wall (``wall``), 0 for what it is not."""
    hand = r.hand_n if r.hand_n is not None else push_n
    device = max(r.device_n, 0.0)
    return {
        "hand": 0.0 if hand is None else max(hand, 0.0),
        "cutting": device if r.kind in ("cutting", "holding") else 0.0,
        "wall": device if r.kind == "wall" else 0.0,
    }


@dataclass(frozen=True)
class StopTiming:
    """The time to the stop: the model's against the session's."""

    predicted_s: float  # inf: the push stalls before the stop
    measured_s: float | None  # None: the session never reached the stop
    agrees: bool
    message: str
    reasons: tuple[str, ...]


def _vibration_reason(table: ProfileTable) -> str | None:
    n = min(table.n_steps, int(table.stop_depth_mm / float(table.depth_step_mm)) + 2)
    s1 = float(np.max(table.s1_n[:n])) if n > 0 else 0.0
    s2 = float(np.max(table.s2_n[:n])) if n > 0 else 0.0
    if s1 <= 0.0 and s2 <= 0.0:
        return None
    f1, f2 = (float(f) for f in table.freqs_hz)
    return (
        f"the cutting vibration (S1 up to {s1:.2f} N at {f1:g} Hz, S2 up to {s2:.2f} N at "
        f"{f2:g} Hz) is rendered on top of the cut and shakes the master; the feed law has no "
        "vibration (on the demo it slows the cut by about 3 %)"
    )


def stop_timing(
    table: ProfileTable,
    push_n: float,
    measured_s: float | None,
    duration_s: float,
    *,
    prediction: PushPrediction | None = None,
) -> StopTiming:
    """Compare the session's time to the stop (None: not reached within ``duration_s``) with
    the model's schedule for a constant ``push_n``; the message says which and why."""
    pred = prediction if prediction is not None else predict_push(table, push_n)
    reasons = pred.reasons()
    vib = _vibration_reason(table)
    if vib is not None:
        reasons.append(vib)
    t = pred.time_to_stop_s
    if measured_s is None and push_n <= 0.0:
        what = "pulls the handle back out of the hole" if push_n < 0.0 else "is no push"
        msg = f"never reached the stop: push {push_n:g} N {what}, so nothing is cut"
        return StopTiming(t, None, True, msg, ())
    if measured_s is None:
        if pred.too_weak:
            msg = (
                f"never reached the stop, as the model predicts: push {push_n:g} N too weak to "
                f"cut at {pred.stall_depth_mm:.2f} mm (S0 = {pred.stall_s0_n:.2f} N); the "
                f"master's {COULOMB_N:g} N friction may hold it a little shallower"
            )
            return StopTiming(t, None, True, msg, tuple(reasons))
        if t > duration_s:
            msg = f"the session ({duration_s:g} s) ended before the model's {t:.2f} s to the stop"
            return StopTiming(t, None, True, msg, tuple(reasons))
        msg = f"did not reach the stop in {duration_s:g} s although the model predicts {t:.2f} s"
        return StopTiming(t, None, False, _why(msg, reasons), tuple(reasons))
    if not math.isfinite(t):
        msg = (
            f"reached the stop after {measured_s:.2f} s although the model predicts a stall at "
            f"{pred.stall_depth_mm:.2f} mm (S0 = {pred.stall_s0_n:.2f} N >= the push)"
        )
        return StopTiming(t, measured_s, False, _why(msg, reasons), tuple(reasons))
    diff = measured_s - t
    within = abs(diff) <= TIME_TOLERANCE_REL * t + TIME_TOLERANCE_S
    rel = f" ({100.0 * diff / t:+.1f} %)" if t > 0.0 else ""
    msg = f"reached the stop after {measured_s:.2f} s; the model's feed predicts {t:.2f} s{rel}"
    if within:
        return StopTiming(t, measured_s, True, msg + ": agrees", tuple(reasons))
    return StopTiming(t, measured_s, False, _why(msg, reasons), tuple(reasons))


def _why(message: str, reasons: list[str]) -> str:
    if not reasons:
        return message + "; the model names no reason for the difference"
    return message + "; why: " + "; ".join(reasons)


def push_summary(
    session: dict[str, Any],
    table: ProfileTable,
    operator_spec: str,
    duration_s: float,
) -> dict[str, Any]:
    """The rehearsal summary's readout keys for a ``push:N`` session (empty for others)."""
    push = push_of(operator_spec)
    if push is None or "time_to_stop_s" not in session:
        return {}
    pred = predict_push(table, push)
    timing = stop_timing(
        table,
        push,
        session.get("time_to_stop_s"),
        duration_s,
        prediction=pred,
    )
    out: dict[str, Any] = {
        "push_n": push,
        "model_time_to_stop_s": timing.predicted_s if math.isfinite(timing.predicted_s) else None,
        "time_to_stop_agrees": timing.agrees,
        "time_to_stop_note": timing.message,
        "push_too_weak_at_mm": pred.stall_depth_mm,
        "push_too_weak_s0_n": pred.stall_s0_n,
    }
    return out


#: Device limits that can let a push through the stop's wall.
WALL_LIMITS = ("peak_limit", "thermal_limit", "travel_limit")
#: A rendered force this close to a limit is at it, N.
AT_LIMIT_N = 0.01


def wall_summary(session: dict[str, Any]) -> dict[str, Any]:
    """The stop's account for a session that reached the stop (empty otherwise).

    ``hand_past_drill_mm`` (the hand's final offset past the stopped drill),
    ``max_hand_past_drill_mm`` (the largest over every sample of the stopped state: the wall
    must be rigid from its first instant), ``wall_held`` (that largest offset within
    :data:`ctdrill.haptics.renderer.WALL_HOLD_MM`) and ``wall_limits``: when the wall did not
    hold, the device limits that let the hand through, read from the force the device rendered
    at the worst sample: its 20 N continuous rating once the thermal limit acted, its 78 N
    peak, and the travel's end stop where the stage came to rest (None when the wall held).
    """
    worst = session.get("max_hand_past_drill_mm")
    if worst is None or session.get("final_master_mm") is None:
        return {}
    stopped = session.get("final_state") == "stopped"
    past = max(float(session["final_master_mm"]) - float(session["final_drill_mm"]), 0.0)
    worst = max(float(worst), past if stopped else 0.0)
    account: dict[str, Any] = {
        "hand_past_drill_mm": past if stopped else None,
        "max_hand_past_drill_mm": worst,
    }
    if worst <= WALL_HOLD_MM:
        return {**account, "wall_held": True, "wall_limits": None}
    at_worst = set(session.get("worst_wall_flags") or [])
    raised = [
        name
        for event in session.get("faults", [])
        if event.get("source") == "device"
        for name in event.get("flags", [])
        if name in WALL_LIMITS
    ]
    force = float(session.get("worst_wall_force_n") or 0.0)
    limits = []
    if "thermal_limit" in at_worst and force <= CONTINUOUS_FORCE_N + AT_LIMIT_N:
        limits.append("thermal_limit")
    elif force >= PEAK_FORCE_N - AT_LIMIT_N:
        limits.append("peak_limit")
    if "travel_limit" in at_worst:
        limits.append("travel_limit")
    return {**account, "wall_held": False, "wall_limits": limits or raised}


def readout_lines(summary: dict[str, Any]) -> str:
    """The CLI's lines on the forces and the time to the stop (``push:N``) and on the stop's
    wall (a session that ended at the stop)."""
    lines = []
    if "push_n" in summary:
        lines.append(f"push {summary['push_n']:g} N: {summary['time_to_stop_note']}")
    if summary.get("hand_past_drill_mm") is not None:
        hand = summary.get("final_hand_est_n")
        hand_text = "" if hand is None else f", the device reads the hand at {hand:.1f} N"
        line = (
            f"at the stop the wall holds {summary['final_force_cmd_n']:.1f} N{hand_text}; the "
            f"hand sits {summary['hand_past_drill_mm']:.2f} mm past the stopped drill"
        )
        worst = summary.get("max_hand_past_drill_mm")
        if worst is not None and worst > summary["hand_past_drill_mm"] + 0.005:
            line += f" (at most {worst:.2f} mm while stopped)"
        if summary.get("wall_limits"):
            names = " then ".join(n.replace("_", " ") for n in summary["wall_limits"])
            line += f" (the device's {names} let it through)"
        lines.append(line)
    return "".join(line + "\n" for line in lines)
