"""Host-side protocol logic shared by the simulated and the serial device.

The host accepts a device frame only when it is of a device->host type and carries the session
nonce that the device's VERSION announced and a sequence number after the last accepted one
(serial-number arithmetic): its own frames echoed by a looped-back line, stale or replayed
device frames and telemetry queued before the session are dropped (counted in
``rejected_frames``). Telemetry and fault reports from before the ARM's acknowledgement are not
part of the session and are discarded.

It holds the device to its own bounds (:mod:`ctdrill.haptics.limits`): VERSION and LIMITS
outside them are refused at HELLO. A FAULT report with a flag or a state this protocol does not
define makes the device untrusted (:meth:`HostDevice.untrusted`); the telemetry itself is judged
by :class:`ctdrill.haptics.watch.TelemetryWatch`.
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from typing import Protocol

from ctdrill.haptics.codes import KNOWN_FAULT_BITS, KNOWN_STATES
from ctdrill.haptics.device import DeviceError, DeviceInfo, DeviceRefused, TelemetrySample
from ctdrill.haptics.limits import device_info_problem, table_problem
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import (
    HOST_TYPES,
    Ack,
    Arm,
    Disarm,
    FaultReport,
    FrameReader,
    Heartbeat,
    Hello,
    Limits,
    Message,
    MsgType,
    Nak,
    NakReason,
    Packet,
    ProfileEnd,
    SimOperator,
    SimReset,
    Stop,
    Telemetry,
    Version,
    encode,
    seq_after,
)

#: Unclaimed replies and NAKs kept (the oldest are dropped).
MAX_KEPT = 256
#: STOP and DISARM are sent again this often until acknowledged, s (the device obeys them
#: whatever their seq: docs/protocol.md section 2.6).
RESEND_S = 0.1


class Transport(Protocol):
    """Byte link to a device plus the notion of time the host runs on."""

    name: str

    def write(self, data: bytes) -> None:
        """Send bytes."""
        ...

    def read(self) -> bytes:
        """Bytes received so far (non-blocking)."""
        ...

    def wait(self, duration_s: float) -> None:
        """Let time pass."""
        ...

    def clock_s(self) -> float:
        """Host clock, s."""
        ...

    def close(self) -> None:
        """Release the link."""
        ...


class HostDevice:
    """A :class:`ctdrill.haptics.device.Device` over any :class:`Transport`.

    Parameters
    ----------
    transport : Transport
    timeout_s : float
        How long a command waits for its ACK/NAK (host clock).
    poll_s : float
        Granularity of that wait.
    token_seed : int, optional
        Seeds HELLO's token (reproducible simulation); default: the OS random source.
    """

    def __init__(
        self,
        transport: Transport,
        *,
        timeout_s: float = 1.0,
        poll_s: float = 0.001,
        token_seed: int | None = None,
    ):
        self.transport = transport
        self.timeout_s = timeout_s
        self.poll_s = poll_s
        self._seq = 0
        self._reader = FrameReader()
        self._telemetry: list[TelemetrySample] = []
        self._replies: list[tuple[Message, int]] = []
        self._tokens: random.Random = (
            random.SystemRandom() if token_seed is None else random.Random(token_seed)
        )
        self._token = -1
        self._arm_seq = -1
        #: The session nonce of the device's VERSION (0: no session yet).
        self.session = 0
        self._device_seq = 0
        self.fault_reports: list[tuple[float, FaultReport]] = []
        self.naks: list[Nak] = []
        self.nak_count = 0
        self.rejected_frames = 0
        self.session_lost = False
        self._untrusted: str | None = None
        self._info: DeviceInfo | None = None
        #: CRC-32 of the table uploaded in this session (ARM names it; 0: none yet).
        self.table_crc32 = 0

    # ------------------------------------------------------------ plumbing

    def send(self, message: Message, *, then: Sequence[Message] = ()) -> int:
        """Send one message in this session, and ``then`` right behind it in the same write
        (the device takes them in at the same tick); returns the first one's sequence
        number."""
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        first = self._seq
        data = encode(message, seq=first, session=self.session)
        for extra in then:
            self._seq = (self._seq + 1) & 0xFFFFFFFF
            data += encode(extra, seq=self._seq, session=self.session)
        self.transport.write(data)
        return first

    def _pump(self) -> None:
        for item in self._reader.feed(self.transport.read()):
            if not isinstance(item, Packet):
                self.rejected_frames += 1
                continue
            msg = item.message
            if msg.TYPE in HOST_TYPES:
                self.rejected_frames += 1  # our own frames, looped back
                continue
            if isinstance(msg, Version) and msg.host_token == self._token and item.session:
                self.session, self._device_seq = item.session, item.seq  # a new session
                self._replies.append((msg, item.seq))
                continue
            if (
                self.session == 0
                or item.session != self.session
                or not seq_after(item.seq, self._device_seq)
            ):
                self.rejected_frames += 1
                if item.session == 0 and self.session:  # the device is up without our session
                    if isinstance(msg, Telemetry):
                        self.session_lost = True
                    elif isinstance(msg, Nak) and msg.reason == NakReason.BAD_SESSION:
                        self.session_lost = True
                        self._replies.append((msg, item.seq))  # a command's answer, at least
                continue
            self._device_seq = item.seq
            self._take(msg, item.time_us * 1e-6, item.seq)

    def _take(self, msg: Message, t: float, seq: int) -> None:
        if isinstance(msg, Telemetry):
            self._telemetry.append(
                TelemetrySample(
                    t,
                    msg.tick,
                    msg.master_mm,
                    msg.drill_mm,
                    msg.velocity_mm_s,
                    msg.force_cmd_n,
                    msg.force_est_n,
                    msg.state,
                    msg.faults,
                    msg.overruns,
                    msg.table_crc32,
                )
            )
            return
        if isinstance(msg, FaultReport):
            self.fault_reports.append((t, msg))
            del self.fault_reports[:-MAX_KEPT]
            unknown = msg.faults & ~KNOWN_FAULT_BITS
            if self._untrusted is None and (unknown or msg.state not in KNOWN_STATES):
                self._untrusted = (
                    f"the device sent a FAULT report with an undefined flag 0x{unknown:04x}"
                    if unknown
                    else f"the device sent a FAULT report with an undefined state {msg.state}"
                )
            return
        if isinstance(msg, Nak):
            self.nak_count += 1
            self.naks.append(msg)
            del self.naks[:-MAX_KEPT]
        elif (
            isinstance(msg, Ack)
            and msg.acked_type == MsgType.ARM
            and msg.acked_seq == self._arm_seq
        ):
            # What the device reported before it armed is not part of the session.
            self._telemetry.clear()
            self.fault_reports.clear()
        self._replies.append((msg, seq))
        del self._replies[:-MAX_KEPT]  # unclaimed replies (e.g. NAKs of SIM_OPERATOR)

    def _await(self, what: str, match: type, *, count: int = 1) -> list[Message]:
        deadline = self.transport.clock_s() + self.timeout_s
        found: list[Message] = []
        while True:
            self._pump()
            keep = []
            for msg, seq in self._replies:
                if isinstance(msg, match) and len(found) < count:
                    found.append(msg)
                else:
                    keep.append((msg, seq))
            self._replies = keep
            if len(found) >= count:
                return found
            if self.transport.clock_s() >= deadline:
                raise DeviceError(
                    f"device on {self.transport.name} did not answer {what} within "
                    f"{self.timeout_s:g} s; check the port, the cable and that the device "
                    "(or 'ctdrill emulate') is running"
                )
            self.transport.wait(self.poll_s)

    def command(
        self, message: Message, *, resend_s: float | None = None, then: Sequence[Message] = ()
    ) -> None:
        """Send a command and wait for its ACK; :class:`DeviceError` on NAK or timeout.

        With ``resend_s`` the command is sent again (with a new seq) every ``resend_s`` until
        one of its copies is answered: for STOP and DISARM, which the device obeys whatever
        their seq, so a copy lost to noise costs ``resend_s``, not the whole timeout. ``then``
        (unacknowledged messages) goes in the same write as the command.
        """
        name = message.TYPE.name
        deadline = self.transport.clock_s() + self.timeout_s
        sent: set[int] = set()
        while True:
            if isinstance(message, Arm):
                self._arm_seq = (self._seq + 1) & 0xFFFFFFFF
            sent.add(self.send(message, then=then))
            again = deadline if resend_s is None else self.transport.clock_s() + resend_s
            while True:
                self._pump()
                for i, (msg, _rseq) in enumerate(self._replies):
                    if (
                        isinstance(msg, Ack | Nak)
                        and msg.acked_seq in sent
                        and msg.acked_type == message.TYPE
                    ):
                        del self._replies[i]
                        if isinstance(msg, Nak):
                            known = {int(r): r.name for r in NakReason}
                            reason = known.get(msg.reason, f"reason {msg.reason}")
                            raise DeviceRefused(
                                f"device on {self.transport.name} refused {name} ({reason})",
                                reason=msg.reason,
                            )
                        return
                now = self.transport.clock_s()
                if now >= deadline:
                    raise DeviceError(
                        f"device on {self.transport.name} did not acknowledge {name} within "
                        f"{self.timeout_s:g} s; check the link"
                    )
                if now >= again:
                    break
                self.transport.wait(self.poll_s)

    # ------------------------------------------------------------ Device API

    def hello(self) -> DeviceInfo:
        """HELLO -> VERSION + LIMITS: a new session.

        What the link buffered before (telemetry the device streamed since power-on) is
        discarded; the VERSION that echoes this HELLO's token sets the session nonce. VERSION
        and LIMITS outside the host's bounds (:mod:`ctdrill.haptics.limits`) are refused
        (:class:`DeviceError`): nothing is uploaded to such a device.
        """
        self.transport.read()  # flush: nothing before our HELLO belongs to the session
        self._reader = FrameReader()
        self._replies.clear()
        self._telemetry.clear()
        self.fault_reports.clear()
        self.session, self._device_seq, self.session_lost = 0, 0, False
        self._untrusted, self._info, self.table_crc32 = None, None, 0
        self._token = self._tokens.randrange(1 << 32)
        self.send(Hello(host_token=self._token))
        (version,) = self._await("HELLO", Version)
        (limits,) = self._await("HELLO", Limits)
        assert isinstance(version, Version) and isinstance(limits, Limits)
        problem = device_info_problem(version, limits)
        if problem is not None:
            raise DeviceError(
                f"device on {self.transport.name} announced {problem}: refused; check that it "
                "is a ctdrill haptic master (docs/protocol.md section 2.5)"
            )
        self._info = DeviceInfo(version, limits)
        return self._info

    def upload_profile(self, table: ProfileTable) -> None:
        """Send BEGIN, the chunks and END; each is acknowledged, END only if the CRC matches.

        A table that does not fit the device's LIMITS is refused before anything is sent.
        """
        if self._info is not None:
            problem = table_problem(self._info.limits, table.n_steps, table.stop_depth_mm)
            if problem is not None:
                raise DeviceError(f"device on {self.transport.name}: {problem}")
        self.table_crc32 = 0
        for message in table.upload_messages():
            self.command(message)
            if isinstance(message, ProfileEnd):
                self.table_crc32 = message.crc32

    def arm(self, *, operator: tuple[int, float] | None = None) -> None:
        """ARM the table uploaded in this session (named by its CRC-32); with ``operator``
        (``(kind, value)``) the simulated hand's first command goes in the same write, so the
        hand starts at the tick the device arms (a session deterministic in device time)."""
        then = () if operator is None else (SimOperator(*operator),)
        self.command(Arm(self.table_crc32), then=then)

    def disarm(self) -> None:
        """DISARM (re-sent every :data:`RESEND_S` until acknowledged)."""
        self.command(Disarm(), resend_s=RESEND_S)

    def stop(self) -> None:
        """STOP (latched safe state; re-sent every :data:`RESEND_S` until acknowledged)."""
        self.command(Stop(), resend_s=RESEND_S)

    def heartbeat(self) -> None:
        """HEARTBEAT (not acknowledged)."""
        self.send(Heartbeat())

    def set_operator(self, kind: int, value: float) -> None:
        """SIM_OPERATOR (not acknowledged)."""
        self.send(SimOperator(kind, value))

    def sim_reset(self) -> None:
        """SIM_RESET (acknowledged, then the device reboots without a session)."""
        self.send(SimReset())

    def lost_session(self) -> bool:
        """True once telemetry arrived without our session (the device rebooted)."""
        self._pump()
        return self.session_lost

    def untrusted(self) -> str | None:
        """Why the host stopped trusting the device's reports (a FAULT report with a flag or
        state this protocol does not define), or None."""
        self._pump()
        return self._untrusted

    def write_raw(self, data: bytes) -> None:
        """Raw bytes to the device."""
        self.transport.write(data)

    def poll(self) -> list[TelemetrySample]:
        """Telemetry received since the last poll."""
        self._pump()
        out, self._telemetry = self._telemetry, []
        return out

    def wait(self, duration_s: float) -> None:
        """Let time pass."""
        self.transport.wait(duration_s)

    def clock_s(self) -> float:
        """Host clock, s."""
        return self.transport.clock_s()

    def close(self) -> None:
        """Release the link."""
        self.transport.close()
