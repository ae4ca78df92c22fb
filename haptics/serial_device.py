"""A device on a serial link (``serial.serial_for_url``): hardware, a pty, or ``loop://``.

A port is opened exclusively (an advisory ``flock``, pyserial's ``exclusive``): a second
ctdrill on the same device is refused ("in use") instead of interleaving its frames.
"""

from __future__ import annotations

import time

import serial

from ctdrill.haptics.device import DeviceError
from ctdrill.haptics.host import HostDevice

BAUDRATE = 2_000_000


class SerialLink:
    """Non-blocking serial transport on the host's monotonic clock."""

    def __init__(self, url: str, *, baudrate: int = BAUDRATE) -> None:
        self.name = url
        exclusive = None if "://" in url else True  # URLs (loop://) have no lock
        try:
            self.port = serial.serial_for_url(
                url, baudrate=baudrate, timeout=0, write_timeout=1.0, exclusive=exclusive
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            if "exclusively lock" in str(exc):
                raise DeviceError(
                    f"serial port {url!r} is in use by another program (another ctdrill "
                    "session?); close it and try again"
                ) from exc
            raise DeviceError(
                f"cannot open serial port {url!r}: {exc}; check the path (or start "
                "'ctdrill emulate --pty-link PATH') and permissions"
            ) from exc

    def write(self, data: bytes) -> None:
        """Send bytes."""
        try:
            self.port.write(data)
        except (serial.SerialException, OSError) as exc:
            raise DeviceError(f"writing to {self.name} failed: {exc}; check the link") from exc

    def read(self) -> bytes:
        """Whatever has arrived."""
        try:
            waiting = self.port.in_waiting
            return bytes(self.port.read(waiting)) if waiting else b""
        except (serial.SerialException, OSError) as exc:
            raise DeviceError(f"reading from {self.name} failed: {exc}; check the link") from exc

    def wait(self, duration_s: float) -> None:
        """Sleep."""
        if duration_s > 0.0:
            time.sleep(duration_s)

    def clock_s(self) -> float:
        """Monotonic clock, s."""
        return time.monotonic()

    def close(self) -> None:
        """Close the port."""
        self.port.close()


class SerialDevice(HostDevice):
    """A :class:`ctdrill.haptics.device.Device` on ``url`` (e.g. ``/dev/ttyUSB0``, a pty, ``loop://``)."""

    def __init__(self, url: str, *, timeout_s: float = 1.0, baudrate: int = BAUDRATE) -> None:
        super().__init__(SerialLink(url, baudrate=baudrate), timeout_s=timeout_s)
