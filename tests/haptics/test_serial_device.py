"""SerialDevice over pyserial URLs: a loopback is not a device, a missing port is bad input."""

from __future__ import annotations

import pytest

from ctdrill.haptics.device import DeviceError
from ctdrill.haptics.protocol import FrameReader, Heartbeat, Packet
from ctdrill.haptics.serial_device import SerialDevice


def test_loopback_carries_frames_but_does_not_answer_hello() -> None:
    dev = SerialDevice("loop://", timeout_s=0.05)
    try:
        dev.heartbeat()
        echoed = dev.transport.read()
        assert [p.message for p in FrameReader().feed(echoed) if isinstance(p, Packet)] == [
            Heartbeat()
        ]
        with pytest.raises(DeviceError, match=r"did not answer HELLO within 0\.05 s"):
            dev.hello()
    finally:
        dev.close()


def test_missing_port_is_a_typed_error() -> None:
    with pytest.raises(DeviceError, match="cannot open serial port '/nonexistent/ttyUSB9'"):
        SerialDevice("/nonexistent/ttyUSB9")
