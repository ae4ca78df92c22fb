"""ctdrill haptics: device protocol, device-side renderer and plant, devices, sessions.

Imports :mod:`model` only (never ``imaging``, ``app`` or a GUI module).
"""

from ctdrill.haptics.device import Device, DeviceError, DeviceInfo, TelemetrySample
from ctdrill.haptics.errors import HapticsInputError
from ctdrill.haptics.profile_table import ProfileTable, ProfileTableError
from ctdrill.haptics.protocol import DeviceState, Fault, ProtocolError
from ctdrill.haptics.serial_device import SerialDevice
from ctdrill.haptics.session import (
    Operator,
    SessionInputError,
    SessionResult,
    parse_fault,
    parse_operator,
    run_session,
)
from ctdrill.haptics.sim import SimulatedDevice

__all__ = [
    "Device",
    "DeviceError",
    "DeviceInfo",
    "DeviceState",
    "Fault",
    "HapticsInputError",
    "Operator",
    "ProfileTable",
    "ProfileTableError",
    "ProtocolError",
    "SerialDevice",
    "SessionInputError",
    "SessionResult",
    "SimulatedDevice",
    "TelemetrySample",
    "parse_fault",
    "parse_operator",
    "run_session",
]
