"""Arming a device whose handle a previous session left deep (docs/protocol.md section 5).

The device refuses ARM (NAK NOT_RETRACTED) while the handle is so far beyond the cut front that
arming would step the force; a new table puts the front back at the entry point, so after a
session that ended at its stop the handle is always too deep. :func:`arm_retracted` then
retracts it: the simulated hand of the emulator is sent back at :data:`RETRACT_FEED_MM_S` (on
hardware, which refuses SIM_OPERATOR, a person retracts the handle), the host watches the
telemetry until the handle is at the entry point, lets go and arms again; after
:data:`RETRACT_WAIT_S` without that it gives up (nothing was armed).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from ctdrill.haptics.device import Device, DeviceRefused, TelemetrySample, simulator_controls
from ctdrill.haptics.limits import TELEMETRY_NUMBERS, telemetry_problem
from ctdrill.haptics.protocol import Limits, NakReason, OperatorKind

#: The simulated hand retracts at this feed, mm/s (60 mm of travel in 1.2 s).
RETRACT_FEED_MM_S = -50.0
#: The handle counts as retracted at or above this depth, mm (the entry point: ARM is accepted
#: there whatever the table, the front being at depth 0 or deeper).
RETRACT_TO_MM = 0.0
#: How long the host waits for the handle, s (a person on hardware needs a moment).
RETRACT_WAIT_S = 30.0
#: After letting go, the host waits this long for the stage to come to rest, s.
SETTLE_S = 0.05


@dataclass(frozen=True)
class Retraction:
    """How the handle was brought back before ARM."""

    from_mm: float
    to_mm: float
    duration_s: float

    def to_json(self) -> dict[str, float]:
        """JSON-ready dict."""
        return {
            "from_mm": round(self.from_mm, 4),
            "to_mm": round(self.to_mm, 4),
            "duration_s": round(self.duration_s, 4),
        }


def arm_retracted(
    device: Device,
    *,
    wait_s: float = RETRACT_WAIT_S,
    block_s: float = 0.01,
    notice: Callable[[str], None] | None = None,
    limits: Limits | None = None,
    operator: tuple[int, float] | None = None,
) -> Retraction | None:
    """ARM ``device`` (a table uploaded in this session); if it refuses NOT_RETRACTED, retract
    the handle and arm again. Returns the retraction (None: armed at once).

    The handle's depth is read from the session's idle telemetry; with ``limits`` (what the
    device announced) a report outside them or not finite is refused, as after ARM.
    ``operator`` (the simulated hand's first command) is sent with each ARM
    (:meth:`Device.arm`); after a refusal the retraction takes the hand over.

    Raises
    ------
    DeviceRefused
        Any other refusal, a report outside ``limits``, or the handle not retracted within
        ``wait_s`` (then nothing is armed and the simulated hand is let go).
    """
    try:
        device.arm(operator=operator)
        return None
    except DeviceRefused as exc:
        if exc.reason != NakReason.NOT_RETRACTED:
            raise
    start = device.clock_s()
    sim = simulator_controls(device)
    depth = _depth(device, block_s, limits=limits)
    if notice is not None:
        notice(
            f"the handle is {depth:.1f} mm deep, beyond the entry point: retracting it "
            "(the simulated hand; on a device, pull the handle back to the entry point)"
        )
    first = depth
    while device.clock_s() - start < wait_s:
        if sim is not None:
            sim.set_operator(int(OperatorKind.FEED), RETRACT_FEED_MM_S)
        device.wait(block_s)
        depth = _depth(device, 0.0, depth, limits=limits)
        if depth > RETRACT_TO_MM:
            continue
        if sim is not None:
            sim.set_operator(int(OperatorKind.NONE), 0.0)
        device.wait(SETTLE_S)
        depth = _depth(device, 0.0, depth, limits=limits)
        try:
            device.arm(operator=operator)
        except DeviceRefused as exc:
            if exc.reason != NakReason.NOT_RETRACTED:
                raise
            continue
        return Retraction(first, depth, device.clock_s() - start)
    if sim is not None:
        sim.set_operator(int(OperatorKind.NONE), 0.0)
    raise DeviceRefused(
        f"the device refused ARM (NOT_RETRACTED): the handle stayed {depth:.1f} mm deep for "
        f"{wait_s:g} s; retract it to the entry point and start again",
        reason=int(NakReason.NOT_RETRACTED),
    )


def _depth(
    device: Device, wait_s: float, last: float = float("inf"), *, limits: Limits | None = None
) -> float:
    """The handle's depth from the latest telemetry (idle telemetry of this session), mm."""
    samples = _heard(device, limits)
    if not samples and wait_s > 0.0:
        device.wait(wait_s)
        samples = _heard(device, limits)
    return samples[-1].master_mm if samples else last


def _heard(device: Device, limits: Limits | None) -> list[TelemetrySample]:
    """The telemetry since the last poll; with ``limits``, none may lie outside them."""
    samples = device.poll()
    if limits is not None:
        for s in samples:
            bad = next(
                (
                    f"a non-finite {n}"
                    for n in TELEMETRY_NUMBERS
                    if not math.isfinite(getattr(s, n))
                ),
                None,
            )
            bad = bad or telemetry_problem(s, limits)
            if bad is not None:
                sim = simulator_controls(device)
                if sim is not None:
                    sim.set_operator(int(OperatorKind.NONE), 0.0)
                raise DeviceRefused(
                    f"while retracting the handle the device reported {bad}: nothing armed; "
                    "check the device (docs/protocol.md section 5)"
                )
    return [s for s in samples if math.isfinite(s.master_mm)]
