"""The messages of the device protocol (docs/protocol.md section 2): one frozen dataclass each.

Each class names its type code (``TYPE``) and its fixed little-endian body layout (``FMT``);
``PROFILE_CHUNK`` has a variable body (1..16 rows). :mod:`ctdrill.haptics.protocol` encodes and
decodes them.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any, ClassVar

from ctdrill.haptics.codes import MsgType

#: Protocol version in every header and in HELLO/VERSION (2: session nonce, 32-bit sequences;
#: 3: CRC-32C frames, host time_us 0, serial-number sequences, session-free STOP and DISARM,
#: ARM and TELEMETRY name the table).
PROTOCOL_VERSION = 3
#: Rows per PROFILE_CHUNK.
MAX_CHUNK_ROWS = 16
ROW = struct.Struct("<fff")


@dataclass(frozen=True)
class Hello:
    """host->device: open a session; the device answers VERSION then LIMITS.

    ``host_token`` is echoed in VERSION so that the host knows the answer is to this HELLO.
    """

    TYPE: ClassVar[MsgType] = MsgType.HELLO
    FMT: ClassVar[struct.Struct] = struct.Struct("<BI")
    protocol_version: int = PROTOCOL_VERSION
    host_token: int = 0


@dataclass(frozen=True)
class Version:
    """device->host: protocol and firmware version, control tick rate, the HELLO's token.

    Its header carries the new session's nonce.
    """

    TYPE: ClassVar[MsgType] = MsgType.VERSION
    FMT: ClassVar[struct.Struct] = struct.Struct("<BBBBII")
    protocol_version: int
    fw_major: int
    fw_minor: int
    fw_patch: int
    tick_rate_hz: int
    host_token: int


@dataclass(frozen=True)
class Limits:
    """device->host: the limits the device enforces."""

    TYPE: ClassVar[MsgType] = MsgType.LIMITS
    FMT: ClassVar[struct.Struct] = struct.Struct("<fffHHff")
    peak_force_n: float
    continuous_force_n: float
    thermal_budget_n2_s: float
    watchdog_ms: int
    max_profile_steps: int
    travel_min_mm: float
    travel_max_mm: float


@dataclass(frozen=True)
class ProfileBegin:
    """host->device: start a profile upload (discards any previous table, disarms)."""

    TYPE: ClassVar[MsgType] = MsgType.PROFILE_BEGIN
    FMT: ClassVar[struct.Struct] = struct.Struct("<Hfffff")
    n_steps: int
    depth_step_mm: float
    ke_per_mm_s: float
    f1_hz: float
    f2_hz: float
    stop_depth_mm: float


@dataclass(frozen=True)
class ProfileChunk:
    """host->device: rows ``first_index ..`` of the table, each ``(s0_n, s1_n, s2_n)``."""

    TYPE: ClassVar[MsgType] = MsgType.PROFILE_CHUNK
    FMT: ClassVar[struct.Struct] = struct.Struct("<HB")
    first_index: int
    rows: tuple[tuple[float, float, float], ...]


@dataclass(frozen=True)
class ProfileEnd:
    """host->device: end of upload with the table's CRC-32; ACK if complete and intact."""

    TYPE: ClassVar[MsgType] = MsgType.PROFILE_END
    FMT: ClassVar[struct.Struct] = struct.Struct("<HI")
    n_steps: int
    crc32: int


@dataclass(frozen=True)
class Arm:
    """host->device: start rendering the table whose CRC-32 is ``table_crc32`` (uploaded in
    this session); the only command that leaves the latched safe state."""

    TYPE: ClassVar[MsgType] = MsgType.ARM
    FMT: ClassVar[struct.Struct] = struct.Struct("<I")
    table_crc32: int


@dataclass(frozen=True)
class Disarm:
    """host->device: zero force, idle (the safe state stays latched: DISARM does not leave it);
    accepted from any host, whatever its session and sequence."""

    TYPE: ClassVar[MsgType] = MsgType.DISARM
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class Heartbeat:
    """host->device: keeps the watchdog fed (any accepted host frame does)."""

    TYPE: ClassVar[MsgType] = MsgType.HEARTBEAT
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class Stop:
    """host->device: emergency stop; the device latches its safe state. Accepted from any
    host, whatever its session and sequence."""

    TYPE: ClassVar[MsgType] = MsgType.STOP
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class SimOperator:
    """host->emulator: the simulated hand (``PUSH`` force N, or ``FEED`` mm/s)."""

    TYPE: ClassVar[MsgType] = MsgType.SIM_OPERATOR
    FMT: ClassVar[struct.Struct] = struct.Struct("<Bf")
    kind: int
    value: float


@dataclass(frozen=True)
class SimReset:
    """host->emulator: simulate a power-cycle reset of the device."""

    TYPE: ClassVar[MsgType] = MsgType.SIM_RESET
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class Telemetry:
    """device->host, every 1 ms: the renderer's state at tick ``tick`` and the CRC-32 of the
    table it holds (0: none)."""

    TYPE: ClassVar[MsgType] = MsgType.TELEMETRY
    FMT: ClassVar[struct.Struct] = struct.Struct("<IfffffBHHI")
    tick: int
    master_mm: float
    drill_mm: float
    velocity_mm_s: float
    force_cmd_n: float
    force_est_n: float
    state: int
    faults: int
    overruns: int
    table_crc32: int


@dataclass(frozen=True)
class FaultReport:
    """device->host: sent once when fault flags are raised."""

    TYPE: ClassVar[MsgType] = MsgType.FAULT
    FMT: ClassVar[struct.Struct] = struct.Struct("<HB")
    faults: int
    state: int


@dataclass(frozen=True)
class Ack:
    """device->host: command ``(acked_type, acked_seq)`` accepted."""

    TYPE: ClassVar[MsgType] = MsgType.ACK
    FMT: ClassVar[struct.Struct] = struct.Struct("<BI")
    acked_type: int
    acked_seq: int


@dataclass(frozen=True)
class Nak:
    """device->host: command refused, with a :class:`NakReason`."""

    TYPE: ClassVar[MsgType] = MsgType.NAK
    FMT: ClassVar[struct.Struct] = struct.Struct("<BIB")
    acked_type: int
    acked_seq: int
    reason: int


Message = (
    Hello
    | Version
    | Limits
    | ProfileBegin
    | ProfileChunk
    | ProfileEnd
    | Arm
    | Disarm
    | Heartbeat
    | Stop
    | SimOperator
    | SimReset
    | Telemetry
    | FaultReport
    | Ack
    | Nak
)

#: Message class of every fixed-size type code.
FIXED: dict[int, Any] = {
    cls.TYPE: cls
    for cls in (
        Hello,
        Version,
        Limits,
        ProfileBegin,
        ProfileEnd,
        Arm,
        Disarm,
        Heartbeat,
        Stop,
        SimOperator,
        SimReset,
        Telemetry,
        FaultReport,
        Ack,
        Nak,
    )
}
