"""The device side a link serves: a :class:`DeviceCore` (bytes in, ticks run, bytes out).

:class:`ctdrill.haptics.emulator.DeviceEmulator` is the Python core; a compiled core (the
reference firmware) is another class with the same members. :data:`CORES` names them for
``ctdrill emulate --core NAME`` and the in-process simulator: a new core is one entry there
(its module imported only when it is chosen). The physics under a core's renderer is
injected separately (:class:`ctdrill.haptics.physics.Physics`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from ctdrill.haptics.physics import Physics


class DeviceCore(Protocol):
    """A device at the wire: protocol, renderer, watchdog and its physics, run tick by tick.

    Attributes
    ----------
    tick_hz : int
        Control rate, Hz.
    ticks : int
        Ticks run since power-on.
    overruns : int
        Ticks its pacer ran late (set by the pacer, reported in telemetry).
    """

    tick_hz: int
    ticks: int
    overruns: int

    @property
    def now_s(self) -> float:
        """Device clock, s."""
        ...

    def receive(self, data: bytes) -> None:
        """Bytes from the host, handled at the current device time."""
        ...

    def take_output(self) -> bytes:
        """Bytes the device wrote since the last call."""
        ...

    def run_ticks(self, n: int) -> None:
        """Run ``n`` control ticks."""
        ...


#: A core's constructor: ``(start_mm=, nonce_seed=, physics=)``.
CoreFactory = Callable[..., DeviceCore]


def _python_core(
    *, start_mm: float = 0.0, nonce_seed: int | None = None, physics: Physics | None = None
) -> DeviceCore:
    from ctdrill.haptics.emulator import DeviceEmulator

    return DeviceEmulator(start_mm=start_mm, nonce_seed=nonce_seed, physics=physics)


def _c_core(
    *, start_mm: float = 0.0, nonce_seed: int | None = None, physics: Physics | None = None
) -> DeviceCore:
    from ctdrill.haptics.ccore import CDeviceEmulator
    from ctdrill.haptics.errors import HapticsInputError

    if physics is not None:
        raise HapticsInputError(
            "--core c: the compiled core runs its own simulated master (firmware/host); "
            "inject a Python physics into --core python"
        )
    return CDeviceEmulator(start_mm=start_mm, nonce_seed=nonce_seed)


#: core name -> its constructor (``ctdrill emulate --core``): ``python`` the emulator of
#: :mod:`ctdrill.haptics.emulator`, ``c`` the reference firmware (``firmware/``, compiled on
#: first use by :mod:`ctdrill.haptics.ccore`).
CORES: dict[str, CoreFactory] = {"python": _python_core, "c": _c_core}


def make_core(
    name: str = "python",
    *,
    start_mm: float = 0.0,
    nonce_seed: int | None = None,
    physics: Physics | None = None,
) -> DeviceCore:
    """A fresh core ``name`` of :data:`CORES` (KeyError names the known ones)."""
    if name not in CORES:
        raise KeyError(f"device core {name!r}: use one of {', '.join(sorted(CORES))}")
    return CORES[name](start_mm=start_mm, nonce_seed=nonce_seed, physics=physics)
