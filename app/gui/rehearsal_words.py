"""What the rehearsal panel says, in plain words for a student (headless).

Each text comes with a tooltip holding the engineering terms (``S0``, ``Ke``, the device's
limits) that the screen itself leaves out; ``summary.json`` keeps them all.
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.app.gui.debrief import Debrief
from ctdrill.app.gui.rehearsal import RehearsalRun, Telemetry
from ctdrill.app.gui.results import stop_explanation
from ctdrill.app.igtl.frames import SLICER_PORT
from ctdrill.app.igtl.stream import stream_line
from ctdrill.app.readout import LiveReadout, push_of, stop_timing
from ctdrill.app.trainee.words import assessment_line
from ctdrill.engine.path import PathResult
from ctdrill.haptics.plant import COULOMB_N
from ctdrill.haptics.predict import predict_push
from ctdrill.haptics.profile_table import ProfileTable

#: The panel's tooltips of the stream to Slicer and of the sound.
IGTL_TIP = (
    "HOST:PORT of an OpenIGTLink server, e.g. 3D Slicer's OpenIGTLinkIF connector on "
    f"localhost:{SLICER_PORT}: the session streams the transforms DrillTip and Implant and the "
    "forces (text Forces, JSON). Empty: off. docs/slicer.md says how to watch it in Slicer."
)
SOUND_TIP = (
    "The cutting vibration at the drill's depth (the model's 30 and 60 Hz amplitudes) on the "
    "audio output; a headset carries 30 Hz better than small speakers"
)


def needed_n(s0_n: float) -> int:
    """The push that cuts where the static cutting force is ``s0_n``, in whole newtons: more
    than ``S0`` (a push at or below it holds)."""
    return math.floor(s0_n) + 1


def need_here_n(r: LiveReadout, push_n: float | None) -> int | None:
    """The push that cuts at the drill's depth, N (None: nothing to cut there): more than
    ``S0``, and where a push above ``S0`` is held by the master's friction (the drill has
    stopped there), more than ``S0`` plus that friction."""
    if r.s0_n <= 0.0:
        return None
    stuck = r.kind == "holding" and push_n is not None and push_n > r.s0_n
    return needed_n(r.s0_n + (COULOMB_N if stuck else 0.0))


def live_words(r: LiveReadout, push_n: float | None) -> tuple[str, str]:
    """``(text, tooltip)`` for one telemetry sample's readout."""
    tip = (
        f"device force {r.device_n:.2f} N ({r.kind}); static cutting force S0 = {r.s0_n:.2f} N "
        f"here, {r.plan_force_n:.2f} N at the plan's feed; {r.status}"
    )
    push = push_n if push_n is not None else r.hand_n
    if r.kind == "off":
        return "The device is off: no force.", tip
    if r.kind == "wall":
        return "At the stop: the drill goes no deeper. Let go, or retract (R).", tip
    if r.kind == "holding":
        if push is None:
            return f"The drill holds: {needed_n(r.s0_n)} N needed to cut here.", tip
        if push <= COULOMB_N:
            return "Push to start: the handle does not move.", tip
        need = need_here_n(r, push) or needed_n(r.s0_n)
        return (
            f"Push harder: {need} N needed to cut here, {need - push:.1f} N more than your "
            f"{push:.1f} N.",
            tip,
        )
    if r.kind == "free":
        if r.s0_n <= 0.0:
            return "No bone here: the drill moves freely.", tip
        return "In the hole: the drill is not touching bone.", tip
    return "Cutting.", tip


def predicted_words(table: ProfileTable, push_n: float) -> tuple[str, str]:
    """``(text, tooltip)``: what a constant ``push_n`` does on ``table`` (the model's
    schedule, :func:`ctdrill.haptics.predict.predict_push`). The push said to reach the stop
    beats the largest ``S0`` ahead by more than the master's friction: a push within that
    friction of ``S0`` may hold or creep (on the demo with ``bone-literature``, 15 N against
    its 14.4 N cortex was 1.95 mm deep after 175 s; 16 N reached the stop in 82 s)."""
    pred = predict_push(table, push_n)
    tip = "; ".join(pred.reasons()) or "the model's feed at this push"
    if push_n <= 0.0:
        return "Set a push to start drilling.", tip
    push = f"{round(push_n, 1):g} N"
    rows = np.arange(table.n_steps) * float(table.depth_step_mm)
    ahead = table.s0_n[rows <= float(table.stop_depth_mm) + 1e-9]
    need = needed_n((float(ahead.max()) if ahead.size else 0.0) + COULOMB_N)
    if pred.too_weak and pred.stall_depth_mm is not None:
        return (
            f"{push} is too weak: the drill stops at {pred.stall_depth_mm:.1f} mm; "
            f"{need} N reaches the stop ({need - push_n:.1f} N more).",
            tip,
        )
    if pred.friction_depth_mm is not None and need > push_n:
        return (
            f"{push} is barely enough: from {pred.friction_depth_mm:.1f} mm the drill may stall "
            f"or creep; {need} N reaches the stop ({need - push_n:.1f} N more).",
            tip,
        )
    return (
        f"At {push} the drill reaches the stop in about {pred.time_to_stop_s:.1f} s.",
        tip,
    )


def end_message(run: RehearsalRun, last: Telemetry | None) -> str:
    """What the panel says when ``run`` ended, from what the device reported (``last``: the
    final telemetry sample, its state the device's own)."""
    state = "none reported" if last is None else last.state
    if run.error:
        return f"error: {run.error} (device state last reported: {state})"
    if run.cancelled:
        events = [] if run.record is None else run.record.get("faults", [])
        acked = bool(events) and all(
            events[-1].get(f"{step}_acknowledged") for step in ("stop", "disarm")
        )
        sent = "STOP and DISARM acknowledged" if acked else "STOP and DISARM not acknowledged"
        return f"stopped by the user: {sent}; device state: {state}"
    s = run.session
    if s is None:
        return f"session ended (device state: {state})"
    reached = s.get("final_state") == "stopped"
    how = "at the auto-stop" if reached else "(its time is up, or the drill came out)"
    return (
        f"session ended {how}: the drill went {s['max_drill_mm']:.2f} mm deep, the stop is at "
        f"{s['stop_depth_mm']:.2f} mm. Export the session to keep it."
    )


def end_details(run: RehearsalRun, last: Telemetry | None) -> str:
    """The end message's tooltip: the engineering account of a session that ran (samples,
    the device's overruns, fault events, its state now); empty otherwise."""
    s = run.session
    if s is None or run.error or run.cancelled:
        return ""
    state = "none reported" if last is None else last.state
    return (
        f"{s['samples']} samples, {s['overruns']} overruns, {len(s.get('faults', ()))} fault "
        f"event(s); device state now: {state}"
    )


def timing_text(run: RehearsalRun) -> str:
    """The time to the stop once ``run`` ended: for a constant push the session's against the
    model's, and why they differ; for the window's hand, when it reached the stop."""
    push = push_of(run.operator_spec)
    record = run.record
    if push is None:
        return "-"
    if record is None or run.cancelled or run.error:
        return predicted_words(run.table, run.push_n)[0]
    reached = record.get("time_to_stop_s")
    if run.live:
        if reached is None:
            return "The drill did not reach the stop."
        return f"You reached the stop after {float(reached):.1f} s."
    ended_s = run.rows[-1][0] if run.rows else run.duration_s
    return stop_timing(run.table, push, reached, ended_s).message


def ended_texts(
    run: RehearsalRun, last: Telemetry | None, debrief: Debrief | None
) -> tuple[str, str]:
    """The panel's message and its tooltip once ``run`` ended (with its score when there is a
    ``debrief``, and the OpenIGTLink stream's line)."""
    text, details = end_message(run, last), end_details(run, last)
    if debrief is not None:
        score = float(debrief.summary["assessment"]["score"])
        text += f" Score {score:.0f} of 100: see the Debrief page."
        details = "\n".join(t for t in (details, assessment_line(debrief.summary)) if t)
    if run.igtl is not None:
        text += f"\n{stream_line(run.igtl)}"
    return text, details


def stop_why(run: RehearsalRun, result: PathResult | None) -> str:
    """Where the device stops the drill, and why (exam mode: its stop beyond the plan;
    ``result``: the path the run drills)."""
    if run.exam is not None:
        return f"exam, no wall at the margin: the stop is at {run.table.stop_depth_mm:.2f} mm"
    return "" if result is None else stop_explanation(result)
