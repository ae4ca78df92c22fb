"""The simulated device: the emulator in-process, device time advanced by the host's waits."""

from __future__ import annotations

from ctdrill.haptics.core import DeviceCore
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.physics import Physics


class SimLink:
    """In-memory byte link to a device core (:class:`DeviceEmulator`); :meth:`wait` runs its
    ticks.

    Host bytes reach the device at once; time passes only in :meth:`wait`, in whole ticks (the
    fractional remainder is carried), so a session is reproducible tick for tick.
    """

    name = "sim"

    def __init__(self, emulator: DeviceCore) -> None:
        self.emulator = emulator
        self._carry_ticks = 0.0

    def write(self, data: bytes) -> None:
        """Deliver bytes to the device."""
        self.emulator.receive(data)

    def read(self) -> bytes:
        """What the device wrote."""
        return self.emulator.take_output()

    def wait(self, duration_s: float) -> None:
        """Run the device for ``duration_s`` of device time."""
        ticks = duration_s * self.emulator.tick_hz + self._carry_ticks
        n = int(ticks + 1e-9)
        self._carry_ticks = ticks - n
        self.emulator.run_ticks(n)

    def clock_s(self) -> float:
        """Device time, s."""
        return self.emulator.now_s

    def close(self) -> None:
        """Nothing to release."""


class SimulatedDevice(HostDevice):
    """A :class:`ctdrill.haptics.device.Device` backed by an in-process :class:`DeviceEmulator`.

    Parameters
    ----------
    start_mm : float
        Initial master depth, mm.
    seed : int
        Seeds the session nonce and the host's HELLO token: a session is reproducible.
    physics : Physics, optional
        The emulator's physics (:mod:`ctdrill.haptics.physics`); default: the paper's master.
    """

    def __init__(
        self,
        *,
        start_mm: float = 0.0,
        timeout_s: float = 1.0,
        seed: int = 0,
        physics: Physics | None = None,
    ) -> None:
        self.emulator = DeviceEmulator(start_mm=start_mm, nonce_seed=seed, physics=physics)
        super().__init__(SimLink(self.emulator), timeout_s=timeout_s, token_seed=seed)
