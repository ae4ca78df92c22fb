"""Which device a session runs on: a :class:`DeviceSpec`, parsed once from ``--device``.

Callers ask the spec (is it simulated, is it paced to the wall clock, what is its label) instead
of comparing its text; :meth:`DeviceSpec.open` returns the :class:`~ctdrill.haptics.device.Device`.
A new kind of device is one entry in :data:`KINDS` and a branch in :meth:`DeviceSpec.open`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ctdrill.haptics.errors import HapticsInputError

if TYPE_CHECKING:
    from ctdrill.haptics.device import Device

#: kind -> simulated (an in-process emulator whose time advances only in the host's waits)
KINDS: dict[str, bool] = {"sim": True, "serial": False}


class DeviceSpecError(HapticsInputError):
    """A ``--device`` text that names no device."""


@dataclass(frozen=True)
class DeviceSpec:
    """A device to open.

    Attributes
    ----------
    kind : str
        A key of :data:`KINDS` (``sim``, ``serial``).
    port : str or None
        The serial port, pty link or pyserial URL (``serial`` only).
    paced : bool
        Device time runs at the wall clock's pace: always for hardware; for the simulator only
        when asked (the window), otherwise it runs as fast as the CPU allows.
    """

    kind: str
    port: str | None = None
    paced: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise DeviceSpecError(f"device kind {self.kind!r}: use one of {', '.join(KINDS)}")
        if self.kind == "serial" and not self.port:
            raise DeviceSpecError("a serial device needs its port: serial:PORT")
        if not self.simulated and not self.paced:
            object.__setattr__(self, "paced", True)  # hardware keeps its own time

    @classmethod
    def simulator(cls, *, paced: bool = False) -> DeviceSpec:
        """The in-process simulator (``paced``: kept to the wall clock)."""
        return cls("sim", paced=paced)

    @classmethod
    def parse(cls, text: str) -> DeviceSpec:
        """``sim`` or ``serial:PORT`` (a device path, a pty link, or a pyserial URL)."""
        if text == "sim":
            return cls.simulator()
        kind, sep, port = text.partition(":")
        if kind == "serial" and sep and port:
            return cls("serial", port)
        raise DeviceSpecError(
            f"--device {text!r}: use sim or serial:PORT (e.g. serial:/dev/ttyUSB0)"
        )

    @property
    def simulated(self) -> bool:
        """An in-process emulator (simulator-only operations and exam mode are allowed)."""
        return KINDS[self.kind]

    @property
    def host_paces(self) -> bool:
        """The host keeps a simulated device to the wall clock (it would run ahead)."""
        return self.simulated and self.paced

    @property
    def label(self) -> str:
        """What ``--device`` said and ``summary.json``'s ``device`` records."""
        return self.kind if self.port is None else f"{self.kind}:{self.port}"

    def open(self, *, seed: int = 0) -> Device:
        """Open the device (``seed``: the simulator's nonces and HELLO token)."""
        if self.kind == "sim":
            from ctdrill.haptics.sim import SimulatedDevice

            return SimulatedDevice(seed=seed)
        from ctdrill.haptics.serial_device import SerialDevice

        return SerialDevice(str(self.port))
