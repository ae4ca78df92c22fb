"""The hands that drive a session: what the host sends as the operator's input every block.

A :class:`Hand` gives the operator command for the block starting at session time ``t_s``
(:meth:`Hand.command`: a :class:`~ctdrill.haptics.protocol.OperatorKind` and its value) and
sees every telemetry sample (:meth:`Hand.observe`), so it can react to what it feels.

* :class:`OperatorHand`: ``push:N``, ``feed:V`` and ``script:FILE`` (they ignore what they feel);
* :class:`HumanHand`: ``human:force=N,react_ms=T[,noise_n=S,seed=K]``, a person who pushes
  with N newtons and lets go T ms after it feels a breakthrough or meets the stop's wall;
* :class:`LiveHand`: a push set from outside while the session runs (the window's mouse and
  keys), with a retraction out of the hole.

The breakthroughs are a property of the table (:func:`breakthrough_depths_mm`): the cutting
force ``S0`` at the drill depth falling below :data:`BREAKTHROUGH_RATIO` of its running peak
over the last :data:`BREAKTHROUGH_WINDOW_MM` of depth. The one that matters
(:func:`decisive_breakthrough_mm`) is the exit from the last layer before a protected
structure or the goal: the first breakthrough at or beyond the planned osteotomy's end (less
the window), never a layer the plan drills through (the crestal cortex's step into soft
trabecular bone in D3/D4). The hand lets go when the drill reaches it while cutting; the
session's assessment (:mod:`ctdrill.haptics.assessment`) times the same event.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from typing import Protocol

import numpy as np

from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.physics import HAND_MAX_N
from ctdrill.haptics.plant import COULOMB_N
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState, OperatorKind
from ctdrill.haptics.session import HumanSpec, Operator

#: A breakthrough: ``S0`` falls below this fraction of its running peak ...
BREAKTHROUGH_RATIO = 0.5
#: ... taken over this much depth behind the drill, mm.
BREAKTHROUGH_WINDOW_MM = 0.5
#: A peak below this is no resistance a hand tells apart from the master's own friction, N.
BREAKTHROUGH_MIN_PEAK_N = COULOMB_N
#: The noise of a ``human`` hand changes at this rate, Hz.
NOISE_RATE_HZ = 100.0
#: A retracting hand draws the handle back at this feed, mm/s ...
RETRACT_MM_S = 5.0
#: ... until the master is out of the hole (at or above this depth), mm.
RETRACTED_MM = 0.0

Command = tuple[int, float]


class Hand(Protocol):
    """The operator of a session (module docstring)."""

    def command(self, t_s: float) -> Command:
        """``(OperatorKind, value)`` for the block starting at session time ``t_s``."""
        ...

    def observe(self, t_s: float, sample: TelemetrySample) -> None:
        """One telemetry sample at session time ``t_s`` (as ``session.csv`` times it)."""
        ...


def breakthrough_depths_mm(table: ProfileTable) -> tuple[float, ...]:
    """Depths where the cutting force breaks through, shallowest first, up to the stop.

    A table row ``i`` at depth ``x`` breaks through when ``S0(x) < BREAKTHROUGH_RATIO * P(x)``
    with ``P(x)`` the largest ``S0`` over ``[x - BREAKTHROUGH_WINDOW_MM, x]`` and ``P(x) >=
    BREAKTHROUGH_MIN_PEAK_N``; each run of such rows counts once, at its first row.
    """
    s0 = table.s0_n.astype(float)
    step = float(table.depth_step_mm)
    window = math.floor(BREAKTHROUGH_WINDOW_MM / step + 1e-6)  # the step is float32
    padded = np.concatenate([np.zeros(window), s0])
    peak = np.lib.stride_tricks.sliding_window_view(padded, window + 1).max(axis=1)
    hit = (peak >= BREAKTHROUGH_MIN_PEAK_N) & (s0 < BREAKTHROUGH_RATIO * peak)
    first = np.flatnonzero(hit & ~np.concatenate([[False], hit[:-1]]))
    depths = first * step
    return tuple(float(d) for d in depths if d <= float(table.stop_depth_mm))


def first_breakthrough_mm(table: ProfileTable) -> float | None:
    """The shallowest breakthrough a session on ``table`` can reach, mm (None: none)."""
    depths = breakthrough_depths_mm(table)
    return depths[0] if depths else None


def decisive_breakthrough_mm(table: ProfileTable) -> float | None:
    """The breakthrough that matters, mm (None: none within the table's stop): the first at
    or beyond ``table.goal_mm - BREAKTHROUGH_WINDOW_MM``, the exit from the last layer before
    the goal or a protected structure beyond it (the canal's roof in an exam). A breakthrough
    shallower than that is a layer the planned osteotomy drills through (the crestal cortex
    into trabecular bone): a hand that let go there would never reach the goal."""
    floor = float(table.goal_mm) - BREAKTHROUGH_WINDOW_MM
    depths = [d for d in breakthrough_depths_mm(table) if d >= floor - 1e-9]
    return depths[0] if depths else None


class OperatorHand:
    """``push:N``, ``feed:V`` and ``script:FILE``: the command follows the clock alone."""

    def __init__(self, operator: Operator) -> None:
        self.operator = operator

    def command(self, t_s: float) -> Command:
        op = self.operator
        if op.kind == "feed":
            return int(OperatorKind.FEED), op.value
        return int(OperatorKind.PUSH), op.force_at_n(t_s)

    def observe(self, t_s: float, sample: TelemetrySample) -> None:
        """It does not react."""


class HumanHand:
    """A person: pushes with ``force_n`` (plus Gaussian noise of ``noise_n`` at 100 Hz, from
    ``seed``) and lets go ``react_ms`` after the first cue: the drill reaching the table's
    decisive breakthrough (:func:`decisive_breakthrough_mm`) while cutting, or the device
    reporting its stop (the wall). Once it has
    let go it stays off the handle (0 N, no noise).

    The host sends the command once per block (10 ms), so the release lands on the first
    block that starts at or after the cue plus ``react_ms``.

    Attributes
    ----------
    cue : tuple of (str, float) or None
        ``("breakthrough" | "wall", session time s)`` of the first cue.
    release_s : float or None
        Session time the hand lets go, s.
    """

    def __init__(self, spec: HumanSpec, table: ProfileTable) -> None:
        self.spec = spec
        self.breakthrough_mm = decisive_breakthrough_mm(table)
        self.cue: tuple[str, float] | None = None
        self.release_s: float | None = None
        self._rng = random.Random(spec.seed)
        self._noise_index = 0
        self._noise_n = self._draw()

    def _draw(self) -> float:
        return self._rng.gauss(0.0, self.spec.noise_n) if self.spec.noise_n > 0.0 else 0.0

    def _noise_at(self, t_s: float) -> float:
        index = math.floor(max(t_s, 0.0) * NOISE_RATE_HZ + 1e-9)
        while self._noise_index < index:
            self._noise_index += 1
            self._noise_n = self._draw()
        return self._noise_n

    def command(self, t_s: float) -> Command:
        if self.release_s is not None and t_s >= self.release_s - 1e-9:
            return int(OperatorKind.PUSH), 0.0
        force = self.spec.force_n + self._noise_at(t_s)
        return int(OperatorKind.PUSH), max(-HAND_MAX_N, min(HAND_MAX_N, force))

    def observe(self, t_s: float, sample: TelemetrySample) -> None:
        if self.cue is not None:
            return
        if sample.state == DeviceState.STOPPED:
            self._feel("wall", t_s)
        elif (
            sample.state == DeviceState.CUTTING
            and self.breakthrough_mm is not None
            and sample.drill_mm >= self.breakthrough_mm
        ):
            self._feel("breakthrough", t_s)

    def _feel(self, what: str, t_s: float) -> None:
        self.cue = (what, t_s)
        self.release_s = t_s + self.spec.react_ms / 1000.0


class LiveHand:
    """A push set from outside while the session runs (the window's hand).

    ``push_n()`` is read every block; while ``retracting()`` is true the hand draws the handle
    back at :data:`RETRACT_MM_S` until the master is out of the hole (depth <=
    :data:`RETRACTED_MM`), then rests (0 N).
    """

    def __init__(self, push_n: Callable[[], float], retracting: Callable[[], bool]) -> None:
        self._push_n = push_n
        self._retracting = retracting
        self.master_mm = 0.0

    def command(self, t_s: float) -> Command:
        if self._retracting():
            if self.master_mm > RETRACTED_MM:
                return int(OperatorKind.FEED), -RETRACT_MM_S
            return int(OperatorKind.PUSH), 0.0
        push = float(self._push_n())
        push = push if math.isfinite(push) else 0.0
        return int(OperatorKind.PUSH), max(-HAND_MAX_N, min(HAND_MAX_N, push))

    def observe(self, t_s: float, sample: TelemetrySample) -> None:
        self.master_mm = sample.master_mm


def hand_for(operator: Operator, table: ProfileTable) -> Hand:
    """The hand that carries out ``operator`` on ``table``."""
    if operator.kind == "human" and operator.human is not None:
        return HumanHand(operator.human, table)
    return OperatorHand(operator)
