"""The device emulator: protocol handling + renderer + force controller + plant + simulated hand.

Bytes in (:meth:`DeviceEmulator.receive`), ticks run (:meth:`DeviceEmulator.run_ticks`), bytes out
(:meth:`DeviceEmulator.take_output`). The same object runs in-process behind
:class:`ctdrill.haptics.sim.SimulatedDevice` (device time as fast as the CPU allows) and on a
pseudo-terminal behind ``ctdrill emulate`` (paced to real time by :mod:`ctdrill.haptics.realtime`).
Fully deterministic: the only state is what it was sent and how many ticks it ran.
"""

from __future__ import annotations

import math

from ctdrill.haptics.plant import TRAVEL_MM, ForceController, MasterPlant
from ctdrill.haptics.profile_table import MAX_PROFILE_STEPS
from ctdrill.haptics.protocol import (
    PROTOCOL_VERSION,
    Ack,
    Arm,
    DeviceState,
    Disarm,
    Fault,
    FaultReport,
    FrameReader,
    Heartbeat,
    Hello,
    Limits,
    Message,
    MessageError,
    Nak,
    NakReason,
    OperatorKind,
    Packet,
    ProfileBegin,
    ProfileChunk,
    ProfileEnd,
    SimOperator,
    SimReset,
    Stop,
    Telemetry,
    UnknownTypeError,
    Version,
    VersionError,
    encode,
    profile_crc32,
)
from ctdrill.haptics.renderer import (
    CONTINUOUS_FORCE_N,
    PEAK_FORCE_N,
    THERMAL_BUDGET_N2_S,
    TICK_HZ,
    WATCHDOG_S,
    Renderer,
)

FW_VERSION = (0, 1, 0)
#: Telemetry every this many ticks (1 kHz at 10 kHz).
TELEMETRY_EVERY = 10
#: The simulated hand in FEED mode: a stiff spring-damper to a reference moving at the feed.
HAND_STIFFNESS_N_PER_MM = 5.0
HAND_DAMPING_N_S_PER_MM = 0.05
HAND_MAX_N = 78.0
MAX_FEED_MM_S = 200.0


class DeviceEmulator:
    """A complete simulated device (see module docstring).

    Parameters
    ----------
    start_mm : float
        Initial master depth, mm.
    tick_hz : int
        Control rate, Hz.
    """

    def __init__(self, *, start_mm: float = 0.0, tick_hz: int = TICK_HZ) -> None:
        self.tick_hz = tick_hz
        self.dt_s = 1.0 / tick_hz
        self.ticks = 0
        self.overruns = 0
        self.start_mm = start_mm
        self.plant = MasterPlant(start_mm=start_mm)
        self.controller = ForceController(start_mm=start_mm, dt_s=self.dt_s)
        self.renderer = Renderer(tick_hz=tick_hz)
        self._reader = FrameReader()
        self._out = bytearray()
        self._seq = 0
        self._upload: ProfileBegin | None = None
        self._rows: list[tuple[float, float, float]] = []
        self.operator_kind = int(OperatorKind.NONE)
        self.operator_value = 0.0
        self._feed_ref_mm = 0.0
        self.hand_n = 0.0
        self.frames_rejected = 0
        self._boot_fault = int(Fault.RESET)

    @property
    def now_s(self) -> float:
        """Device clock, s."""
        return self.ticks * self.dt_s

    # ------------------------------------------------------------ I/O

    def _send(self, message: Message) -> None:
        self._seq = (self._seq + 1) & 0xFFFF
        self._out += encode(message, seq=self._seq, time_us=self.ticks * 1_000_000 // self.tick_hz)

    def take_output(self) -> bytes:
        """Bytes the device has written since the last call."""
        out = bytes(self._out)
        self._out.clear()
        return out

    def receive(self, data: bytes) -> None:
        """Bytes from the host, handled at the current device time."""
        for item in self._reader.feed(data):
            if isinstance(item, Packet):
                self.renderer.host_frame(self.now_s)
                self._handle(item)
            else:
                self.frames_rejected += 1
                reason = NakReason.BAD_FRAME
                if isinstance(item, UnknownTypeError):
                    reason = NakReason.UNKNOWN_TYPE
                elif isinstance(item, VersionError):
                    reason = NakReason.BAD_VERSION
                elif isinstance(item, MessageError):
                    reason = NakReason.BAD_LENGTH
                self._send(Nak(0, 0, int(reason)))

    # ------------------------------------------------------------ commands

    def _handle(self, packet: Packet) -> None:
        msg = packet.message
        seq = packet.seq
        r = self.renderer
        now = self.now_s
        if isinstance(msg, Heartbeat):
            return
        if isinstance(msg, Hello):
            self._send(Version(PROTOCOL_VERSION, *FW_VERSION, self.tick_hz))
            self._send(
                Limits(
                    PEAK_FORCE_N,
                    CONTINUOUS_FORCE_N,
                    THERMAL_BUDGET_N2_S,
                    round(WATCHDOG_S * 1000),
                    MAX_PROFILE_STEPS,
                    *TRAVEL_MM,
                )
            )
            return
        if isinstance(msg, SimOperator):
            self._set_operator(msg)
            return
        reason = self._command(msg, now)
        if reason is None:
            self._send(Ack(int(msg.TYPE), seq))
        else:
            self._send(Nak(int(msg.TYPE), seq, int(reason)))
        if r.new_faults:
            self._report_faults()

    def _command(self, msg: Message, now: float) -> NakReason | None:
        r = self.renderer
        if isinstance(msg, ProfileBegin):
            values = (msg.depth_step_mm, msg.ke_per_mm_s, msg.f1_hz, msg.f2_hz, msg.stop_depth_mm)
            self._upload = None
            if not all(math.isfinite(v) for v in values):
                return NakReason.NONFINITE
            if not 1 <= msg.n_steps <= MAX_PROFILE_STEPS:
                return NakReason.PROFILE_TOO_LONG
            if msg.depth_step_mm <= 0.0 or min(values[1:]) < 0.0:
                return NakReason.BAD_VALUE
            r.clear()
            self._upload, self._rows = msg, []
            return None
        if isinstance(msg, ProfileChunk):
            if self._upload is None or msg.first_index != len(self._rows):
                self._upload = None
                return NakReason.PROFILE_ORDER
            if len(self._rows) + len(msg.rows) > self._upload.n_steps:
                self._upload = None
                return NakReason.PROFILE_TOO_LONG
            for row in msg.rows:
                if not all(math.isfinite(v) for v in row):
                    self._upload = None
                    return NakReason.NONFINITE
                if row[0] < 0.0:
                    self._upload = None
                    return NakReason.BAD_VALUE
            self._rows.extend(msg.rows)
            return None
        if isinstance(msg, ProfileEnd):
            begin, self._upload = self._upload, None
            if begin is None or msg.n_steps != begin.n_steps or len(self._rows) != begin.n_steps:
                return NakReason.PROFILE_ORDER
            if profile_crc32(begin, self._rows) != msg.crc32:
                return NakReason.PROFILE_CRC
            r.load(begin, self._rows)
            return None
        if isinstance(msg, Arm):
            refused = r.arm(now, self.plant.encoder_mm())
            if refused is None:
                self._boot_fault = 0
            return refused
        if isinstance(msg, Disarm):
            r.disarm()
            return None
        if isinstance(msg, Stop):
            r.host_stop(now)
            return None
        if isinstance(msg, SimReset):
            self.reset()
            return None
        return NakReason.UNKNOWN_TYPE  # device->host types sent to the device

    def _set_operator(self, msg: SimOperator) -> None:
        if not math.isfinite(msg.value) or msg.kind not in tuple(OperatorKind):
            return
        if msg.kind == OperatorKind.FEED and (
            self.operator_kind != OperatorKind.FEED or msg.value != self.operator_value
        ):
            self._feed_ref_mm = self.plant.position_mm
        self.operator_kind = msg.kind
        limit = HAND_MAX_N if msg.kind == OperatorKind.PUSH else MAX_FEED_MM_S
        self.operator_value = max(-limit, min(limit, msg.value))

    def reset(self) -> None:
        """Power cycle: table and state lost (the stage stays where it is); RESET reported."""
        self.renderer = Renderer(tick_hz=self.tick_hz)
        self.controller = ForceController(start_mm=self.plant.encoder_mm(), dt_s=self.dt_s)
        self._upload = None
        self._reader = FrameReader()
        self._boot_fault = int(Fault.RESET)

    def _report_faults(self) -> None:
        r = self.renderer
        self._send(FaultReport(r.new_faults, r.state))
        r.new_faults = 0

    # ------------------------------------------------------------ ticks

    def _hand_force_n(self) -> float:
        kind = self.operator_kind
        if kind == OperatorKind.PUSH:
            return self.operator_value
        if kind == OperatorKind.FEED:
            self._feed_ref_mm += self.operator_value * self.dt_s
            force = HAND_STIFFNESS_N_PER_MM * (
                self._feed_ref_mm - self.plant.position_mm
            ) + HAND_DAMPING_N_S_PER_MM * (self.operator_value - self.plant.v_m_s * 1e3)
            return max(-HAND_MAX_N, min(HAND_MAX_N, force))
        return 0.0

    def run_ticks(self, n: int) -> None:
        """Run ``n`` control ticks (telemetry every :data:`TELEMETRY_EVERY`)."""
        r = self.renderer
        c = self.controller
        p = self.plant
        dt = self.dt_s
        for _ in range(n):
            self.ticks += 1
            now = self.ticks * dt
            x_mm = p.encoder_mm()
            # the velocity estimate is the previous tick's (the controller updates it below)
            force = r.tick(now, x_mm, c.velocity_mm_s)
            state = r.state
            if state == DeviceState.CUTTING or state == DeviceState.STOPPED:
                current = c.update(x_mm, force)
            else:
                current = c.idle(x_mm)
            hand = self._hand_force_n()
            self.hand_n = hand
            p.step(current, hand, dt)
            if r.new_faults:
                self._report_faults()
            if self.ticks % TELEMETRY_EVERY == 0:
                self._telemetry()

    def _telemetry(self) -> None:
        r = self.renderer
        c = self.controller
        faults = r.faults | self._boot_fault
        if self.plant.at_end_stop:
            faults |= Fault.TRAVEL_LIMIT
        self._send(
            Telemetry(
                self.ticks & 0xFFFFFFFF,
                self.plant.encoder_mm(),
                r.drill_mm,
                c.velocity_mm_s,
                r.force_cmd_n,
                c.hand_est_n,
                r.state,
                faults,
                min(self.overruns, 0xFFFF),
            )
        )
