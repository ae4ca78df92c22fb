"""What the rehearsal panel says in a blind trial (:mod:`ctdrill.app.gui.blind`): no prediction
of the push, no word of the force the bone resists with."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ctdrill.app.readout import LiveReadout

#: What the panel says instead of the push's prediction (it names none).
BLIND_PREDICTION = "A blind trial: feel the bone as the drill goes down, then name its class below."


def blind_live_words(r: LiveReadout, push_n: float | None) -> tuple[str, str]:
    """``(text, tooltip)`` of a live readout in a blind trial: what the drill does, never the
    force the bone resists with or the push it needs."""
    if r.kind == "off":
        return "The device is off: no force.", ""
    if r.kind == "wall":
        return "At the stop: the drill goes no deeper. Let go, or retract (R).", ""
    if r.kind == "holding":
        push = push_n if push_n is not None else r.hand_n
        if push is not None and push <= 1.0:
            return "Push to start: the handle does not move.", ""
        return "The drill holds: push harder to cut.", ""
    if r.kind == "free":
        return "The drill is not cutting.", ""
    return "Cutting.", ""
