"""The device emulator: protocol handling + renderer + the device's physics (force controller,
mechanism and simulated hand: an injected :class:`ctdrill.haptics.physics.Physics`, by
default the paper's master, :class:`ctdrill.haptics.physics.MasterPhysics`).

Bytes in (:meth:`DeviceEmulator.receive`), ticks run (:meth:`DeviceEmulator.run_ticks`), bytes out
(:meth:`DeviceEmulator.take_output`). The same object runs in-process behind
:class:`ctdrill.haptics.sim.SimulatedDevice` (device time as fast as the CPU allows) and on a
pseudo-terminal behind ``ctdrill emulate`` (paced to real time by :mod:`ctdrill.haptics.realtime`).
Deterministic for a given ``nonce_seed``: the only state is what it was sent and how many ticks
it ran (without a seed, session nonces come from the operating system's random source).

Frames from the host are accepted (and feed the watchdog) only when they decode, are of a
host->device type with ``time_us`` 0, and, except HELLO, carry the current session's nonce and
a sequence number after the last accepted one (serial-number arithmetic): a looped-back line, a
replayed frame or a frame of an earlier session is rejected and never keeps the device armed.
STOP and DISARM are the exception that makes the device safer: they are carried out whatever
their session and sequence (an emergency stop from any host), without feeding the watchdog
unless they are also the session's next frame. ARM needs a table uploaded in this session and
names it by its CRC-32; TELEMETRY names the table the device holds.
"""

from __future__ import annotations

import math
import random

from ctdrill.haptics.physics import MasterPhysics, Physics
from ctdrill.haptics.plant import ForceController, MasterPlant
from ctdrill.haptics.profile_table import MAX_PROFILE_STEPS
from ctdrill.haptics.protocol import (
    DEVICE_TYPES,
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
    Packet,
    ProfileBegin,
    ProfileChunk,
    ProfileEnd,
    ProtocolError,
    SimOperator,
    SimReset,
    Stop,
    Telemetry,
    UnknownTypeError,
    Version,
    VersionError,
    encode,
    profile_crc32,
    seq_after,
)
from ctdrill.haptics.renderer import (
    CONTINUOUS_FORCE_N,
    PEAK_FORCE_N,
    THERMAL_BUDGET_N2_S,
    WATCHDOG_S,
    Renderer,
)
from ctdrill.haptics.tick import TICK_HZ

FW_VERSION = (0, 1, 0)
#: Telemetry every this many ticks (1 kHz at 10 kHz).
TELEMETRY_EVERY = 10


class DeviceEmulator:
    """A complete simulated device (see module docstring).

    Parameters
    ----------
    start_mm : float
        Initial master depth, mm.
    tick_hz : int
        Control rate, Hz.
    nonce_seed : int, optional
        Seeds the session nonces (reproducible simulation); default: the OS random source.
    physics : Physics, optional
        The controller, mechanism and hand (ticking at ``tick_hz``); default: the paper's
        master at ``start_mm``.
    """

    def __init__(
        self,
        *,
        start_mm: float = 0.0,
        tick_hz: int = TICK_HZ,
        nonce_seed: int | None = None,
        physics: Physics | None = None,
    ) -> None:
        self.tick_hz = tick_hz
        self.dt_s = 1.0 / tick_hz
        self.ticks = 0
        self.overruns = 0
        self.start_mm = start_mm
        self.physics: Physics = (
            physics if physics is not None else MasterPhysics(start_mm=start_mm, dt_s=self.dt_s)
        )
        self.renderer = Renderer(tick_hz=tick_hz)
        self._reader = FrameReader()
        self._out = bytearray()
        self._seq = 0
        self._upload: ProfileBegin | None = None
        self._rows: list[tuple[float, float, float]] = []
        self.hand_n = 0.0
        self.frames_rejected = 0
        self._boot_fault = int(Fault.RESET)
        self._nonces: random.Random = (
            random.SystemRandom() if nonce_seed is None else random.Random(nonce_seed)
        )
        #: The session nonce chosen at the last HELLO (0: no session since power-on).
        self.session = 0
        #: The sequence number of the last accepted host frame of this session.
        self.host_seq = 0
        #: CRC-32 of the installed table (0: none) and the session that uploaded it.
        self.table_crc32 = 0
        self.table_session = 0

    @property
    def now_s(self) -> float:
        """Device clock, s."""
        return self.ticks * self.dt_s

    def _master(self) -> MasterPhysics:
        if not isinstance(self.physics, MasterPhysics):
            raise AttributeError("this emulator's physics is not the master's plant")
        return self.physics

    @property
    def plant(self) -> MasterPlant:
        """The master's plant (default physics only)."""
        return self._master().plant

    @plant.setter
    def plant(self, plant: MasterPlant) -> None:
        self._master().plant = plant

    @property
    def controller(self) -> ForceController:
        """The master's force controller (default physics only)."""
        return self._master().controller

    @controller.setter
    def controller(self, controller: ForceController) -> None:
        self._master().controller = controller

    # ------------------------------------------------------------ I/O

    def _send(self, message: Message, *, session: int | None = None) -> None:
        """Frame ``message`` with the device's next seq (one counter since power-on, wrapping)
        and the current session, or ``session`` (the reply to a STOP or DISARM of another)."""
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        self._out += encode(
            message,
            seq=self._seq,
            session=self.session if session is None else session,
            time_us=self.ticks * 1_000_000 // self.tick_hz,
        )

    def take_output(self) -> bytes:
        """Bytes the device has written since the last call."""
        out = bytes(self._out)
        self._out.clear()
        return out

    def receive(self, data: bytes) -> None:
        """Bytes from the host, handled at the current device time."""
        for item in self._reader.feed(data):
            if isinstance(item, Packet):
                self._accept(item)
            else:
                self._refuse(item)

    def _refuse(self, error: ProtocolError) -> None:
        """A frame that did not decode: NAK it (never feeds the watchdog)."""
        self.frames_rejected += 1
        if error.header is not None and error.header[0] in DEVICE_TYPES:
            return  # a device->host type: looped back; a reply would circulate forever
        reason = NakReason.BAD_FRAME
        if isinstance(error, UnknownTypeError):
            reason = NakReason.UNKNOWN_TYPE
        elif isinstance(error, VersionError):
            reason = NakReason.BAD_VERSION
        elif isinstance(error, MessageError):
            reason = NakReason.BAD_LENGTH
        mtype, seq = (error.header[0], error.header[1]) if error.header else (0, 0)
        self._send(Nak(mtype, seq, int(reason)))

    def _accept(self, packet: Packet) -> None:
        """A decoded frame: check direction, header, session and sequence, then handle it."""
        msg = packet.message
        if msg.TYPE in DEVICE_TYPES:
            self.frames_rejected += 1  # looped back (or a confused host): dropped, no reply
            return
        if packet.time_us != 0:  # a host frame has no clock: no free bytes in its header
            self.frames_rejected += 1
            self._send(Nak(int(msg.TYPE), packet.seq, int(NakReason.BAD_HEADER)))
            return
        if isinstance(msg, Hello):
            self._hello(packet.seq, msg)
            return
        current = self.session != 0 and packet.session == self.session
        if current and seq_after(packet.seq, self.host_seq):
            self.host_seq = packet.seq
            self.renderer.host_frame(self.now_s)
            self._handle(packet)
            return
        if isinstance(msg, Stop | Disarm):  # the safe direction: from any host, any seq
            self._safe_command(msg, packet)
            return
        self.frames_rejected += 1
        reason = NakReason.STALE_SEQUENCE if current else NakReason.BAD_SESSION
        self._send(Nak(int(msg.TYPE), packet.seq, int(reason)))

    def _safe_command(self, msg: Stop | Disarm, packet: Packet) -> None:
        """STOP or DISARM outside the session's sequence: carried out, acknowledged in the
        sender's session (so that it knows its answer), the watchdog not fed."""
        if isinstance(msg, Stop):
            self.renderer.host_stop(self.now_s)
        else:
            self.renderer.disarm()
        self._send(Ack(int(msg.TYPE), packet.seq), session=packet.session)
        if self.renderer.new_faults:
            self._report_faults()

    def _hello(self, seq: int, msg: Hello) -> None:
        """HELLO: a new session (nonce, sequences), the device disarmed; VERSION and LIMITS."""
        if msg.protocol_version != PROTOCOL_VERSION:
            self.frames_rejected += 1
            self._send(Nak(int(msg.TYPE), seq, int(NakReason.BAD_VERSION)))
            return
        self.session = self._nonces.randrange(1, 1 << 32)
        self.host_seq = seq
        self._upload = None
        self.renderer.disarm()  # an armed session ends with its host (safe stays latched)
        self.renderer.host_frame(self.now_s)
        self._send(Version(PROTOCOL_VERSION, *FW_VERSION, self.tick_hz, msg.host_token))
        self._send(
            Limits(
                PEAK_FORCE_N,
                CONTINUOUS_FORCE_N,
                THERMAL_BUDGET_N2_S,
                round(WATCHDOG_S * 1000),
                MAX_PROFILE_STEPS,
                *self.physics.travel_mm,
            )
        )

    def _handle(self, packet: Packet) -> None:
        msg = packet.message
        if isinstance(msg, Heartbeat):
            return
        if isinstance(msg, SimOperator):
            refused = self._set_operator(msg)
            if refused is not None:  # accepted operator inputs are not acknowledged
                self._send(Nak(int(msg.TYPE), packet.seq, int(refused)))
            return
        if isinstance(msg, SimReset):
            self._send(Ack(int(msg.TYPE), packet.seq))  # the last frame of the session
            self.reset()
            return
        reason = self._command(msg, self.now_s)
        if reason is None:
            self._send(Ack(int(msg.TYPE), packet.seq))
        else:
            self._send(Nak(int(msg.TYPE), packet.seq, int(reason)))
        if self.renderer.new_faults:
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
            self.table_crc32 = self.table_session = 0
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
            self.table_crc32, self.table_session = msg.crc32, self.session
            return None
        if isinstance(msg, Arm):
            if not r.has_profile or self.table_session != self.session:
                return NakReason.NOT_READY  # no table uploaded in this session
            if msg.table_crc32 != self.table_crc32:
                return NakReason.PROFILE_CRC  # not the table the host means
            refused = r.arm(now, self.physics.encoder_mm())
            if refused is None:
                self._boot_fault = 0
            return refused
        if isinstance(msg, Disarm):
            r.disarm()
            return None
        if isinstance(msg, Stop):
            r.host_stop(now)
            return None
        return NakReason.UNKNOWN_TYPE  # not reached: every host type is handled above

    def _set_operator(self, msg: SimOperator) -> NakReason | None:
        """The simulated hand's input (:meth:`ctdrill.haptics.physics.Physics.set_operator`)."""
        return self.physics.set_operator(msg.kind, msg.value)

    def reset(self) -> None:
        """Power cycle: table, session and state lost (the stage stays where it is, the hand
        keeps doing what it did); RESET reported; unsent output is kept (it left before)."""
        self.renderer = Renderer(tick_hz=self.tick_hz)
        self.physics.power_cycle()
        self._upload = None
        self._reader = FrameReader()
        self._boot_fault = int(Fault.RESET)
        self.session = 0
        self.host_seq = 0
        self._seq = 0
        self.table_crc32 = self.table_session = 0

    def _report_faults(self) -> None:
        r = self.renderer
        self._send(FaultReport(r.new_faults, r.state))
        r.new_faults = 0

    # ------------------------------------------------------------ ticks

    def run_ticks(self, n: int) -> None:
        """Run ``n`` control ticks (telemetry every :data:`TELEMETRY_EVERY`)."""
        for _ in range(n):
            self.control_tick()
            if self.renderer.new_faults:
                self._report_faults()
            if self.ticks % TELEMETRY_EVERY == 0:
                self._telemetry()

    def control_tick(self) -> None:
        """One control tick without I/O: renderer, then the physics (controller, hand,
        mechanism; the loop :mod:`ctdrill.haptics.stability_sim` also runs)."""
        r = self.renderer
        ph = self.physics
        self.ticks += 1
        # the velocity and hand estimates are the previous tick's (the physics updates them)
        force = r.tick(self.ticks * self.dt_s, ph.encoder_mm(), ph.velocity_mm_s, ph.hand_est_n)
        state = r.state
        ph.step(force, engaged=state == DeviceState.CUTTING or state == DeviceState.STOPPED)
        self.hand_n = ph.hand_n

    def _telemetry(self) -> None:
        r = self.renderer
        ph = self.physics
        faults = r.faults | self._boot_fault
        if ph.at_end_stop:
            faults |= Fault.TRAVEL_LIMIT
        self._send(
            Telemetry(
                self.ticks & 0xFFFFFFFF,
                ph.encoder_mm(),
                r.drill_mm,
                ph.velocity_mm_s,
                r.force_cmd_n,
                ph.hand_est_n,
                r.state,
                faults,
                min(self.overruns, 0xFFFF),
                self.table_crc32,
            )
        )
