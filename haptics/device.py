"""The host's view of a haptic device: one small Protocol, two implementations.

:class:`ctdrill.haptics.sim.SimulatedDevice` runs the device emulator in-process (device time
advances only in :meth:`Device.wait`, as fast as the CPU allows, deterministic);
:class:`ctdrill.haptics.serial_device.SerialDevice` talks to real hardware or ``ctdrill emulate``
over ``serial.serial_for_url`` (``/dev/ttyUSB0``, a pty path, ``loop://``) in real time. Both share
the host logic of :class:`ctdrill.haptics.host.HostDevice`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from ctdrill.haptics.errors import HapticsInputError
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import Limits, Version


class DeviceError(HapticsInputError):
    """The device did not answer, or refused a command; the message says what to check."""


class DeviceRefused(DeviceError):
    """The device answered a command with NAK (it did not carry it out).

    ``reason`` is the NAK's reason code (:class:`ctdrill.haptics.protocol.NakReason`), or None
    when the host refused on its own.
    """

    def __init__(self, message: str, *, reason: int | None = None) -> None:
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class DeviceInfo:
    """What HELLO returned."""

    version: Version
    limits: Limits


@dataclass(frozen=True)
class TelemetrySample:
    """One TELEMETRY frame, in host units.

    Attributes
    ----------
    time_s : float
        Device clock, s.
    tick : int
        Device tick counter.
    master_mm, drill_mm : float
        Master depth and drill depth, mm.
    velocity_mm_s, force_cmd_n, force_est_n : float
        Master velocity, rendered force (>= 0 opposes advance) and the hand-force estimate.
    state : int
        :class:`ctdrill.haptics.protocol.DeviceState`.
    faults : int
        :class:`ctdrill.haptics.protocol.Fault` bits.
    overruns : int
        Control ticks the device ran late.
    table_crc32 : int
        CRC-32 of the table the device holds (0: none).
    """

    time_s: float
    tick: int
    master_mm: float
    drill_mm: float
    velocity_mm_s: float
    force_cmd_n: float
    force_est_n: float
    state: int
    faults: int
    overruns: int
    table_crc32: int = 0


class Device(Protocol):
    """Host API of a haptic device (simulated or serial); what only a simulator or emulator
    carries out is :class:`SimulatorControls`."""

    def hello(self) -> DeviceInfo:
        """Open the session: version and limits; raises :class:`DeviceError` on no answer."""
        ...

    def upload_profile(self, table: ProfileTable) -> None:
        """Send the table; returns once the device verified its CRC-32 (else DeviceError)."""
        ...

    def arm(self, *, operator: tuple[int, float] | None = None) -> None:
        """Start rendering the table uploaded in this session (the only way out of a latched
        safe state); ``operator``: the simulated hand's first command, sent with the ARM (the
        hand starts at the tick the device arms)."""
        ...

    def disarm(self) -> None:
        """Zero force, idle (a latched safe state stays safe)."""
        ...

    def stop(self) -> None:
        """Emergency stop: the device latches its safe state."""
        ...

    def heartbeat(self) -> None:
        """Feed the device watchdog (send at least every 50 ms while armed)."""
        ...

    def poll(self) -> list[TelemetrySample]:
        """Telemetry of this session received since the last poll, oldest first (after ARM:
        only what the device sent once armed)."""
        ...

    def lost_session(self) -> bool:
        """True once the device sent telemetry without the session (it rebooted)."""
        ...

    def untrusted(self) -> str | None:
        """Why the host stopped trusting the device's reports, or None."""
        ...

    def wait(self, duration_s: float) -> None:
        """Let ``duration_s`` of time pass (simulated: runs the device; serial: sleeps)."""
        ...

    def clock_s(self) -> float:
        """Host clock, s (simulated: the device clock; serial: monotonic)."""
        ...

    def close(self) -> None:
        """Release the link."""
        ...


@runtime_checkable
class SimulatorControls(Protocol):
    """What a host may ask of a simulated device or an emulator on a link (the simulated
    hand, fault injection); real hardware refuses SIM_OPERATOR and SIM_RESET."""

    def set_operator(self, kind: int, value: float) -> None:
        """Simulated hand (:class:`ctdrill.haptics.protocol.OperatorKind` and its value)."""
        ...

    def write_raw(self, data: bytes) -> None:
        """Raw bytes to the device (fault injection)."""
        ...

    def sim_reset(self) -> None:
        """Ask the emulator to power-cycle (fault injection)."""
        ...


def simulator_controls(device: Device) -> SimulatorControls | None:
    """``device``'s simulator controls, or None for a device without them."""
    return device if isinstance(device, SimulatorControls) else None
