"""Code tables of the device protocol: message types, states, fault flags, NAK reasons."""

from __future__ import annotations

from enum import IntEnum


class MsgType(IntEnum):
    """Message type codes (header byte 1)."""

    HELLO = 0x01
    VERSION = 0x02
    LIMITS = 0x03
    PROFILE_BEGIN = 0x10
    PROFILE_CHUNK = 0x11
    PROFILE_END = 0x12
    ARM = 0x20
    DISARM = 0x21
    HEARTBEAT = 0x22
    STOP = 0x23
    SIM_OPERATOR = 0x28
    SIM_RESET = 0x29
    TELEMETRY = 0x30
    FAULT = 0x31
    ACK = 0x40
    NAK = 0x41


#: Types the host sends (the device accepts only these; every type has one direction).
HOST_TYPES: frozenset[int] = frozenset(
    {
        MsgType.HELLO,
        MsgType.PROFILE_BEGIN,
        MsgType.PROFILE_CHUNK,
        MsgType.PROFILE_END,
        MsgType.ARM,
        MsgType.DISARM,
        MsgType.HEARTBEAT,
        MsgType.STOP,
        MsgType.SIM_OPERATOR,
        MsgType.SIM_RESET,
    }
)
#: Types the device sends (a device receiving one drops it: a looped-back line).
DEVICE_TYPES: frozenset[int] = frozenset(
    {
        MsgType.VERSION,
        MsgType.LIMITS,
        MsgType.TELEMETRY,
        MsgType.FAULT,
        MsgType.ACK,
        MsgType.NAK,
    }
)


class DeviceState(IntEnum):
    """Renderer states reported in TELEMETRY and FAULT."""

    IDLE = 0
    CUTTING = 1
    STOPPED = 2
    SAFE = 3


class Fault(IntEnum):
    """Fault flag bits (u16) in TELEMETRY and FAULT."""

    WATCHDOG = 1 << 0
    NONFINITE = 1 << 1
    THERMAL_LIMIT = 1 << 2
    PEAK_LIMIT = 1 << 3
    HOST_STOP = 1 << 4
    PROFILE_INVALID = 1 << 5
    RESET = 1 << 6
    TRAVEL_LIMIT = 1 << 7


#: Every state and every fault bit this protocol defines (anything else is a device the host
#: cannot interpret: it ends the session).
KNOWN_STATES: frozenset[int] = frozenset(int(s) for s in DeviceState)
KNOWN_FAULT_BITS: int = sum(int(f) for f in Fault)


class NakReason(IntEnum):
    """Why the device refused a command (NAK body)."""

    BAD_FRAME = 1
    UNKNOWN_TYPE = 2
    BAD_LENGTH = 3
    BAD_VERSION = 4
    NOT_READY = 5
    PROFILE_CRC = 6
    PROFILE_ORDER = 7
    NONFINITE = 8
    PROFILE_TOO_LONG = 9
    BAD_VALUE = 10
    NOT_RETRACTED = 11
    BAD_SESSION = 12
    STALE_SEQUENCE = 13
    BAD_HEADER = 14


class OperatorKind(IntEnum):
    """SIM_OPERATOR kinds (simulator and emulator only; a real device NAKs the message)."""

    NONE = 0
    PUSH = 1
    FEED = 2
