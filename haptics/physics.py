"""What an emulated device drives and senses each tick: its physics behind one small Protocol.

The emulator (:class:`ctdrill.haptics.emulator.DeviceEmulator`) owns the protocol, the
session rules and the renderer; everything below the renderer's force command is a
:class:`Physics`: the device's force controller, the mechanism it moves and the (simulated)
hand on the handle. :class:`MasterPhysics` is the paper's master (Table 4:
:class:`~ctdrill.haptics.plant.MasterPlant` under
:class:`~ctdrill.haptics.plant.ForceController`) with :class:`SimulatedHand`. Another
mechanism (a slave plant, a second device model, a compiled controller) is a class with the
same methods handed to ``DeviceEmulator(physics=...)``; the emulator is not edited.

One tick, in this order (the emulator's :meth:`~DeviceEmulator.control_tick`): the renderer
reads :meth:`Physics.encoder_mm`, :attr:`Physics.velocity_mm_s` and :attr:`Physics.hand_est_n`
(the previous tick's estimates) and returns its force command; :meth:`Physics.step` runs the
controller on it (or idles it when the renderer is not ``engaged``: IDLE, SAFE), applies the
hand and advances the mechanism by one tick.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

from ctdrill.haptics.plant import TRAVEL_MM, ForceController, MasterPlant
from ctdrill.haptics.protocol import NakReason, OperatorKind
from ctdrill.haptics.renderer import PEAK_FORCE_N

#: The simulated hand in FEED mode: a stiff spring-damper to a reference moving at the feed.
HAND_STIFFNESS_N_PER_MM = 5.0
HAND_DAMPING_N_S_PER_MM = 0.05
#: The simulated hand's bounds (SIM_OPERATOR values beyond them are clamped; ``--operator``
#: and operator scripts are refused beyond them): it pushes at most the device's peak force,
#: and feeds at most 200 mm/s.
HAND_MAX_N = PEAK_FORCE_N
HAND_MAX_FEED_MM_S = 200.0


class Physics(Protocol):
    """The controller, mechanism and hand of an emulated device (module docstring).

    Depths in mm (+ into the patient), forces in N (a force command >= 0 opposes advance).
    """

    @property
    def travel_mm(self) -> tuple[float, float]:
        """The mechanism's travel (end stops), mm: reported in LIMITS."""
        ...

    @property
    def velocity_mm_s(self) -> float:
        """The controller's velocity estimate, mm/s."""
        ...

    @property
    def hand_est_n(self) -> float:
        """The controller's reading of the hand's force along +depth, N."""
        ...

    @property
    def hand_n(self) -> float:
        """The hand's true force in the last tick, N (simulation only; never sent)."""
        ...

    @property
    def at_end_stop(self) -> bool:
        """True while the mechanism sits at an end stop (TRAVEL_LIMIT in telemetry)."""
        ...

    def encoder_mm(self) -> float:
        """The position sensor's reading, mm."""
        ...

    def step(self, force_cmd_n: float, *, engaged: bool) -> None:
        """One tick: the controller (``engaged``: rendering ``force_cmd_n``; else idle), the
        hand, the mechanism."""
        ...

    def set_operator(self, kind: int, value: float) -> NakReason | None:
        """The simulated hand's input (SIM_OPERATOR); a reason refuses it."""
        ...

    def power_cycle(self) -> None:
        """The device rebooted: the controller restarts where the mechanism is (which, and the
        hand, carry on)."""
        ...


class SimulatedHand:
    """The hand SIM_OPERATOR drives: PUSH N (negative pulls the handle back), FEED mm/s
    (negative retracts; a spring-damper to a reference moving at the feed), NONE (no hand).

    Attributes
    ----------
    kind : int
        :class:`~ctdrill.haptics.protocol.OperatorKind` of the last accepted input.
    value : float
        Its value (N or mm/s), clamped to :data:`HAND_MAX_N` / :data:`HAND_MAX_FEED_MM_S`.
    """

    def __init__(self) -> None:
        self.kind = int(OperatorKind.NONE)
        self.value = 0.0
        self.feed_ref_mm = 0.0

    def set(self, kind: int, value: float, position_mm: float) -> NakReason | None:
        """A new input with the handle at ``position_mm``. Values beyond the bounds are clamped;
        NaN, inf or an unknown kind are refused and the hand keeps its previous input."""
        if kind not in tuple(OperatorKind):
            return NakReason.BAD_VALUE
        if not math.isfinite(value):
            return NakReason.NONFINITE
        if kind == OperatorKind.FEED and (self.kind != OperatorKind.FEED or value != self.value):
            self.feed_ref_mm = position_mm
        self.kind = kind
        limit = HAND_MAX_N if kind == OperatorKind.PUSH else HAND_MAX_FEED_MM_S
        self.value = max(-limit, min(limit, value))
        return None

    def force_n(self, position_mm: float, velocity_mm_s: float, dt_s: float) -> float:
        """The hand's force over the next tick on a handle at ``position_mm`` moving at
        ``velocity_mm_s``, N (FEED advances its reference by one tick)."""
        if self.kind == OperatorKind.PUSH:
            return self.value
        if self.kind == OperatorKind.FEED:
            self.feed_ref_mm += self.value * dt_s
            force = HAND_STIFFNESS_N_PER_MM * (
                self.feed_ref_mm - position_mm
            ) + HAND_DAMPING_N_S_PER_MM * (self.value - velocity_mm_s)
            return max(-HAND_MAX_N, min(HAND_MAX_N, force))
        return 0.0


class MasterPhysics:
    """The paper's master: :class:`MasterPlant` under :class:`ForceController`, with a
    :class:`SimulatedHand`.

    Parameters
    ----------
    start_mm : float
        Initial depth, mm.
    dt_s : float
        Control tick, s.
    coulomb_n : float, optional
        The plant's and the controller's friction model, N (default: Table 4's).
    """

    def __init__(
        self, *, start_mm: float = 0.0, dt_s: float, coulomb_n: float | None = None
    ) -> None:
        self.dt_s = dt_s
        self._friction: dict[str, Any] = {} if coulomb_n is None else {"coulomb_n": coulomb_n}
        self.plant = MasterPlant(start_mm=start_mm, **self._friction)
        self.controller = ForceController(start_mm=start_mm, dt_s=dt_s, **self._friction)
        self.hand = SimulatedHand()
        self._hand_n = 0.0

    @property
    def travel_mm(self) -> tuple[float, float]:
        return TRAVEL_MM

    @property
    def velocity_mm_s(self) -> float:
        return self.controller.velocity_mm_s

    @property
    def hand_est_n(self) -> float:
        return self.controller.hand_est_n

    @property
    def hand_n(self) -> float:
        return self._hand_n

    @property
    def at_end_stop(self) -> bool:
        return self.plant.at_end_stop

    def encoder_mm(self) -> float:
        return self.plant.encoder_mm()

    def step(self, force_cmd_n: float, *, engaged: bool) -> None:
        c, p = self.controller, self.plant
        x_mm = p.encoder_mm()
        current = c.update(x_mm, force_cmd_n) if engaged else c.idle(x_mm)
        hand = self.hand.force_n(p.position_mm, p.v_m_s * 1e3, self.dt_s)
        self._hand_n = hand
        p.step(current, hand, self.dt_s)

    def set_operator(self, kind: int, value: float) -> NakReason | None:
        return self.hand.set(kind, value, self.plant.position_mm)

    def power_cycle(self) -> None:
        self.controller = ForceController(
            start_mm=self.plant.encoder_mm(), dt_s=self.dt_s, **self._friction
        )
