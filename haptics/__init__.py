"""ctdrill haptics: device protocol, device-side renderer and plant, devices, sessions.

Imports :mod:`model` only (never ``imaging``, ``app`` or a GUI module). The names below are
re-exported lazily (PEP 562): each loads its module on first use, so importing
:mod:`ctdrill.haptics.errors` does not load the serial link, the simulator or NumPy.
:data:`_EXPORTS` is the one table of which module defines each name; the ``TYPE_CHECKING``
imports say the same to mypy (``tests/test_architecture.py`` checks that the two agree).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctdrill.lazy import attach

if TYPE_CHECKING:
    from ctdrill.haptics.device import (
        Device,
        DeviceError,
        DeviceInfo,
        DeviceRefused,
        TelemetrySample,
    )
    from ctdrill.haptics.errors import HapticsInputError
    from ctdrill.haptics.profile_table import ProfileTable, ProfileTableError
    from ctdrill.haptics.protocol import DeviceState, Fault, ProtocolError
    from ctdrill.haptics.run import SessionResult, run_session
    from ctdrill.haptics.serial_device import SerialDevice
    from ctdrill.haptics.session import (
        Operator,
        SessionInputError,
        parse_fault,
        parse_operator,
    )
    from ctdrill.haptics.sim import SimulatedDevice

#: public name -> the module that defines it (imported on first access)
_EXPORTS: dict[str, str] = {
    "Device": "ctdrill.haptics.device",
    "DeviceError": "ctdrill.haptics.device",
    "DeviceInfo": "ctdrill.haptics.device",
    "DeviceRefused": "ctdrill.haptics.device",
    "DeviceState": "ctdrill.haptics.protocol",
    "Fault": "ctdrill.haptics.protocol",
    "HapticsInputError": "ctdrill.haptics.errors",
    "Operator": "ctdrill.haptics.session",
    "ProfileTable": "ctdrill.haptics.profile_table",
    "ProfileTableError": "ctdrill.haptics.profile_table",
    "ProtocolError": "ctdrill.haptics.protocol",
    "SerialDevice": "ctdrill.haptics.serial_device",
    "SessionInputError": "ctdrill.haptics.session",
    "SessionResult": "ctdrill.haptics.run",
    "SimulatedDevice": "ctdrill.haptics.sim",
    "TelemetrySample": "ctdrill.haptics.device",
    "parse_fault": "ctdrill.haptics.session",
    "parse_operator": "ctdrill.haptics.session",
    "run_session": "ctdrill.haptics.run",
}

__all__ = [
    "Device",
    "DeviceError",
    "DeviceInfo",
    "DeviceRefused",
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


__getattr__, __dir__ = attach(__name__, _EXPORTS)
