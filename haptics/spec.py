"""Which device a session runs on: a :class:`DeviceSpec`, parsed once from ``--device``.

Callers ask the spec (is it simulated, is it paced to the wall clock, what is its label) instead
of comparing its text; :meth:`DeviceSpec.open` returns the :class:`~ctdrill.haptics.device.Device`.
The kinds are :data:`KINDS`: a new device is one :class:`DeviceKind` there (a simulated one
hands its own :class:`~ctdrill.haptics.physics.Physics` to
:class:`~ctdrill.haptics.sim.SimulatedDevice`); ``--device`` reads ``KIND`` or ``KIND:PORT``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ctdrill.haptics.errors import HapticsInputError

if TYPE_CHECKING:
    from ctdrill.haptics.device import Device


class DeviceSpecError(HapticsInputError):
    """A ``--device`` text that names no device."""


@dataclass(frozen=True)
class DeviceKind:
    """A kind of device.

    Attributes
    ----------
    simulated : an in-process emulator whose time advances only in the host's waits (the
        simulator-only operations and exam mode are allowed).
    needs_port : ``--device KIND:PORT`` (a serial port, pty link or pyserial URL).
    opener : ``(spec, seed) -> Device``; imports its modules only when called.
    """

    simulated: bool
    needs_port: bool
    opener: Callable[[DeviceSpec, int], Device]


def _open_sim(spec: DeviceSpec, seed: int) -> Device:
    from ctdrill.haptics.sim import SimulatedDevice

    return SimulatedDevice(seed=seed)


def _open_serial(spec: DeviceSpec, seed: int) -> Device:
    from ctdrill.haptics.serial_device import SerialDevice

    return SerialDevice(str(spec.port))


#: kind -> how it is opened (``--device``).
KINDS: dict[str, DeviceKind] = {
    "sim": DeviceKind(simulated=True, needs_port=False, opener=_open_sim),
    "serial": DeviceKind(simulated=False, needs_port=True, opener=_open_serial),
}


def _forms() -> str:
    return " or ".join(f"{k}:PORT" if v.needs_port else k for k, v in KINDS.items())


@dataclass(frozen=True)
class DeviceSpec:
    """A device to open.

    Attributes
    ----------
    kind : str
        A key of :data:`KINDS` (``sim``, ``serial``).
    port : str or None
        The serial port, pty link or pyserial URL (kinds that need one).
    paced : bool
        Device time runs at the wall clock's pace: always for hardware; for a simulated
        device only when asked (the window), otherwise it runs as fast as the CPU allows.
    """

    kind: str
    port: str | None = None
    paced: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise DeviceSpecError(f"device kind {self.kind!r}: use {_forms()}")
        if KINDS[self.kind].needs_port and not self.port:
            raise DeviceSpecError(f"a {self.kind} device needs its port: {self.kind}:PORT")
        if not self.simulated and not self.paced:
            object.__setattr__(self, "paced", True)  # hardware keeps its own time

    @classmethod
    def simulator(cls, *, paced: bool = False) -> DeviceSpec:
        """The in-process simulator (``paced``: kept to the wall clock)."""
        return cls("sim", paced=paced)

    @classmethod
    def parse(cls, text: str) -> DeviceSpec:
        """``KIND`` or ``KIND:PORT`` of :data:`KINDS` (``sim``, ``serial:/dev/ttyUSB0``)."""
        kind, sep, port = text.partition(":")
        entry = KINDS.get(kind)
        if entry is not None and (bool(sep and port) if entry.needs_port else not sep):
            return cls(kind, port or None)
        example = next((f"{k}:/dev/ttyUSB0" for k, v in KINDS.items() if v.needs_port), "sim")
        raise DeviceSpecError(f"--device {text!r}: use {_forms()} (e.g. {example})")

    @property
    def simulated(self) -> bool:
        """An in-process emulator (simulator-only operations and exam mode are allowed)."""
        return KINDS[self.kind].simulated

    @property
    def host_paces(self) -> bool:
        """The host keeps a simulated device to the wall clock (it would run ahead)."""
        return self.simulated and self.paced

    @property
    def label(self) -> str:
        """What ``--device`` said and ``summary.json``'s ``device`` records."""
        return self.kind if self.port is None else f"{self.kind}:{self.port}"

    def open(self, *, seed: int = 0) -> Device:
        """Open the device (``seed``: a simulator's nonces and HELLO token)."""
        return KINDS[self.kind].opener(self, seed)
