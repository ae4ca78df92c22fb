"""The OpenIGTLink sender: a thread of its own behind a latest-value slot.

The session's host loop calls :meth:`IgtlStream.observe` with each block's telemetry (its
``on_samples`` observer, every 10 ms): that stores the block's newest sample in a one-frame
slot and returns (one reference stored: no lock, no wake-up, no packing, no socket). The
sender thread connects (once, with a timeout), then looks at the slot ``MAX_RATE_HZ`` times a
second and sends a frame it has not sent yet, packed whole
(:func:`ctdrill.app.igtl.frames.frame_messages`). A frame replaced in the
slot before the sender took it is *dropped*: a slow peer gets fewer, newer frames, never a
queue of old ones. The socket's send buffer is kept small (``SEND_BUFFER_BYTES``) so the
kernel does not queue seconds of old poses either.

Failures never reach the session: a refused or failed connection, a lost one, or a peer that
accepts nothing for ``STALL_TIMEOUT_S`` (it stopped reading) ends the streaming with one
warning (``on_warning``) and the reason in :class:`StreamReport` ``error``; the session goes
on. Pyigtl (its message classes) packs the messages; the socket is ours, so that a dead peer
costs bounded time and is reported once.

A drill sequence streams every drill's session through one connection:
:meth:`IgtlStream.start_drill` before each session names the drill (``Drill``) and restarts
the session time; the frames then carry that drill's axis, implant and name.
"""

from __future__ import annotations

import contextlib
import math
import socket
import struct
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ctdrill.app.igtl.frames import (
    DRILL_TIP,
    FORCES,
    IMPLANT,
    IgtlTarget,
    StreamDrill,
    StreamGeometry,
    frame_messages,
)
from ctdrill.haptics.device import TelemetrySample

#: Connecting gives up after this long, s.
CONNECT_TIMEOUT_S = 2.0
#: A send that cannot hand its bytes to the kernel for this long means the peer stopped
#: reading, s: the stream ends (a lost connection).
STALL_TIMEOUT_S = 2.0
#: The socket's send buffer (the kernel doubles it): about 0.2 s of frames at 100 Hz.
SEND_BUFFER_BYTES = 8192
#: A frame: (header timestamp s, session time s, the sample, the axis, the drill or None).
_Frame = tuple[float, float, TelemetrySample, StreamGeometry, StreamDrill | None]
#: ``Implant`` (a fixed pose) is sent with the first frame and then at this period, s.
IMPLANT_PERIOD_S = 1.0
#: :meth:`IgtlStream.close` waits this long for the last frame, s; a sender still blocked
#: then is cut off (its peer stalled).
CLOSE_GRACE_S = 0.25
#: The sender looks for a new frame this often, Hz: the most frames it sends a second. No
#: viewer draws faster, and an unpaced simulator offers thousands a second (a sender busy
#: packing them would take the interpreter from the session's loop).
MAX_RATE_HZ = 200.0
#: A server that reads keeps its receive window open: once it holds more unread than this,
#: bytes (more than half a second of frames), it is not reading (a port that listens and never
#: accepts: the kernel takes the bytes, no program does) and the stream ends with an error.
UNREAD_LIMIT_BYTES = 16 * 1024
#: After the last frame, a reading server's window reopens within this, s; what it still
#: holds unread then beyond :data:`UNREAD_SLACK_BYTES` was never taken.
DRAIN_WAIT_S = 0.15
#: The sender looks at what the server holds unread this often, s.
UNREAD_CHECK_S = 0.25
UNREAD_SLACK_BYTES = 2048
#: ``struct tcp_info``'s ``tcpi_snd_wnd`` (Linux 5.4+): the window the peer advertises.
_TCPI_SND_WND = struct.Struct("<I")
_TCPI_SND_WND_AT = 228


@dataclass
class StreamReport:
    """What a stream did (``summary.json`` ``igtl``).

    Attributes
    ----------
    host, port : the server.
    connected : the connection was made.
    frames : frames the session offered (one per telemetry block, 100 Hz of session time).
    sent : frames sent whole (``DrillTip`` and ``Forces``, with ``Implant`` when due).
    dropped : ``frames - sent``: replaced in the slot by a newer one before the sender took
        it, or offered when there was no connection.
    send_rate_hz : ``(sent - 1) / span`` of the sent frames' header timestamps (None: fewer
        than two sent).
    messages : messages sent per name (``Drill`` too when a drill sequence sent it).
    error : why streaming stopped early (None: it did not).
    """

    host: str
    port: int
    connected: bool = False
    frames: int = 0
    sent: int = 0
    dropped: int = 0
    send_rate_hz: float | None = None
    messages: dict[str, int] = field(default_factory=lambda: {DRILL_TIP: 0, FORCES: 0, IMPLANT: 0})
    error: str | None = None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict, in the attributes' order."""
        return {
            "host": self.host,
            "port": self.port,
            "connected": self.connected,
            "frames": self.frames,
            "sent": self.sent,
            "dropped": self.dropped,
            "send_rate_hz": self.send_rate_hz,
            "messages": dict(self.messages),
            "error": self.error,
        }


class IgtlStream:
    """Streams a session's frames to one OpenIGTLink server (module docstring).

    Parameters
    ----------
    target : the server (:func:`ctdrill.app.igtl.frames.parse_target`).
    geometry : the plan's axis and implant.
    on_warning : called once, from the sender thread, with the line to show when streaming
        fails (``OpenIGTLink HOST:PORT: ...; the session goes on without streaming``).
    pace : keep the session at the wall clock's pace (:meth:`observe` sleeps while the
        session's time runs ahead of it): the simulator otherwise runs many times faster
        than real time, which no viewer can follow. Never for a real device.
    """

    def __init__(
        self,
        target: IgtlTarget,
        geometry: StreamGeometry,
        *,
        on_warning: Callable[[str], None] | None = None,
        pace: bool = False,
        stall_timeout_s: float = STALL_TIMEOUT_S,
        connect_timeout_s: float = CONNECT_TIMEOUT_S,
        send_buffer_bytes: int = SEND_BUFFER_BYTES,
    ) -> None:
        import pyigtl  # noqa: F401  (lazily, here: not inside the session's first block)

        self.target = target
        self.geometry = geometry
        self.on_warning = on_warning
        self.pace = pace
        self.stall_timeout_s = stall_timeout_s
        self.connect_timeout_s = connect_timeout_s
        self.send_buffer_bytes = send_buffer_bytes
        self.report = StreamReport(target.host, target.port)
        #: The newest frame: written by the session only (one reference store), read by the
        #: sender only.
        self._slot: _Frame | None = None
        self._drill: StreamDrill | None = None
        self._closing = False
        self._error_lock = threading.Lock()
        self._sock: socket.socket | None = None
        #: The widest receive window the server advertised, bytes (None: not known).
        self._max_window: int | None = None
        self._t0: float | None = None
        self._wall0 = 0.0
        self._stamps = (math.nan, math.nan)  # first and last sent header timestamps
        self._thread = threading.Thread(target=self._run, name="ctdrill-igtl", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ session side
    def observe(self, samples: Sequence[TelemetrySample]) -> None:
        """A block's telemetry (the session's ``on_samples``): offer its newest sample.

        No lock and no wake-up call: one reference stored where the sender finds it at its
        next poll (every ``1 / MAX_RATE_HZ``).
        """
        if not samples:
            return
        if self._t0 is None:
            self._t0 = samples[0].time_s  # the session's time 0, as session.csv's
            self._wall0 = time.monotonic()
        sample = samples[-1]
        t = sample.time_s - self._t0
        if math.isfinite(sample.drill_mm):
            self._slot = (time.time(), t, sample, self.geometry, self._drill)
            self.report.frames += 1
        if self.pace:
            ahead = t - (time.monotonic() - self._wall0)
            if ahead > 0.0:
                time.sleep(ahead)

    def start_drill(self, geometry: StreamGeometry, drill: StreamDrill) -> None:
        """A drill sequence's next session (call between sessions, from the session side):
        its frames carry ``geometry`` and ``drill`` (sent as ``Drill`` with its first frame)
        and its session time starts again at 0 (as its ``session.csv``)."""
        self.geometry = geometry
        self._drill = drill
        self._t0 = None

    def chained(self, first: Callable[[list[TelemetrySample]], None]) -> Callable[..., None]:
        """An ``on_samples`` observer calling ``first``, then :meth:`observe`."""

        def both(samples: list[TelemetrySample]) -> None:
            first(samples)
            self.observe(samples)

        return both

    def close(self) -> StreamReport:
        """Send the last frame (waiting at most ``CLOSE_GRACE_S``), close, and report."""
        self._closing = True
        self._thread.join(CLOSE_GRACE_S + DRAIN_WAIT_S)
        if self._thread.is_alive():  # blocked connecting, or sending to a peer that does not read
            if not self.report.connected:
                self._fail(f"no connection within the session ({self.connect_timeout_s:g} s)")
            else:
                self._fail(
                    f"the server stopped reading (the last frame was not taken within "
                    f"{CLOSE_GRACE_S:g} s of the session's end)"
                )
            sock = self._sock
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.shutdown(socket.SHUT_RDWR)
            self._thread.join(CLOSE_GRACE_S)
        report = self.report
        report.dropped = report.frames - report.sent
        span = self._stamps[1] - self._stamps[0]
        if report.sent >= 2 and span > 0.0:
            report.send_rate_hz = round((report.sent - 1) / span, 1)
        return report

    # ------------------------------------------------------------------ sender thread
    def _fail(self, what: str) -> None:
        with self._error_lock:
            if self.report.error is not None:
                return
            self.report.error = what
        if self.on_warning is not None:
            self.on_warning(
                f"OpenIGTLink {self.target.text}: {what}; the session goes on without streaming"
            )

    def _connect(self) -> socket.socket | None:
        try:
            infos = socket.getaddrinfo(self.target.host, self.target.port, type=socket.SOCK_STREAM)
        except OSError as exc:
            self._fail(f"cannot resolve the host ({exc})")
            return None
        problem: OSError | None = None
        for family, kind, proto, _name, address in infos:
            sock = socket.socket(family, kind, proto)
            self._sock = sock
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, self.send_buffer_bytes)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                sock.settimeout(self.connect_timeout_s)
                sock.connect(address)
            except OSError as exc:
                problem = exc
                sock.close()
                continue
            sock.settimeout(self.stall_timeout_s)
            return sock
        why = "refused" if isinstance(problem, ConnectionRefusedError) else str(problem)
        self._fail(
            f"cannot connect ({why}: is 3D Slicer's OpenIGTLinkIF connector started as a "
            f"server on port {self.target.port}?)"
        )
        return None

    def _run(self) -> None:
        sock = self._connect()
        if sock is None:
            return
        self.report.connected = True
        self._max_window = _peer_window(sock)
        sent: _Frame | None = None
        drill_sent: StreamDrill | None = None
        next_implant = -math.inf
        next_check = time.monotonic() + UNREAD_CHECK_S
        try:
            while True:
                closing = self._closing  # read before the slot: the last frame still goes
                item = self._slot
                if item is not None and item is not sent:
                    sent = item
                    due = item[0] >= next_implant
                    name_drill = item[4] is not None and (due or item[4] is not drill_sent)
                    if not self._send(sock, item, with_implant=due, with_drill=name_drill):
                        return
                    now = time.monotonic()
                    if now >= next_check:  # a look at the server's queue, 4 times a second
                        next_check = now + UNREAD_CHECK_S
                        if self._unread(sock) > UNREAD_LIMIT_BYTES:
                            self._fail_unread(sock)
                            return
                    drill_sent = item[4]
                    if due:
                        next_implant = item[0] + IMPLANT_PERIOD_S
                if closing:
                    self._drained(sock)
                    return
                time.sleep(1.0 / MAX_RATE_HZ)
        finally:
            with contextlib.suppress(OSError):
                sock.close()

    def _unread(self, sock: socket.socket) -> int:
        """How much the server holds unread, bytes: on this machine its socket's receive
        queue (``/proc/net/tcp``: exact, whether or not a program ever accepted it); else how
        far its receive window has shrunk from the widest it advertised (0 where the system
        does not tell)."""
        queued = _local_peer_queue(sock)
        if queued is not None:
            return queued
        window = _peer_window(sock)
        if window is None or self._max_window is None:
            return 0
        self._max_window = max(self._max_window, window)
        return self._max_window - window

    def _fail_unread(self, sock: socket.socket) -> None:
        self._fail(
            f"the server is not reading: at least {self._unread(sock)} bytes sent were never taken "
            "(a port that listens but never accepts the connection?)"
        )

    def _drained(self, sock: socket.socket) -> None:
        """After the last frame: the server took what was sent, or the stream's error."""
        deadline = time.monotonic() + DRAIN_WAIT_S
        while self._unread(sock) > UNREAD_SLACK_BYTES:
            if time.monotonic() >= deadline:
                self._fail_unread(sock)
                return
            time.sleep(0.01)

    def _send(
        self, sock: socket.socket, item: _Frame, *, with_implant: bool, with_drill: bool
    ) -> bool:
        """Send one frame whole; False (and the stream's error) when the peer failed."""
        stamp, t, sample, geometry, drill = item
        messages = frame_messages(
            geometry,
            sample,
            t,
            timestamp=stamp,
            with_implant=with_implant,
            drill=drill if with_drill else None,
        )
        try:
            sock.sendall(b"".join(m.pack() for m in messages))
        except TimeoutError:
            self._fail(f"the server stopped reading (nothing taken for {self.stall_timeout_s:g} s)")
            return False
        except OSError as exc:
            self._fail(f"the connection was lost ({exc})")
            return False
        report = self.report
        report.sent += 1
        for m in messages:
            report.messages[m.device_name] = report.messages.get(m.device_name, 0) + 1
        self._stamps = (self._stamps[0] if report.sent > 1 else stamp, stamp)
        return True


def _proc_address(address: tuple[Any, ...], family: int) -> str:
    """``address`` as ``/proc/net/tcp{,6}`` writes it: the IP's 32-bit words in host order
    (little-endian here), hex, then ``:PORT`` in hex."""
    raw = socket.inet_pton(family, address[0])
    words = "".join(f"{w:08X}" for w in struct.unpack(f"<{len(raw) // 4}I", raw))
    return f"{words}:{address[1]:04X}"


def _local_peer_queue(sock: socket.socket) -> int | None:
    """The receive queue of the server's end of ``sock`` when it lives on this machine
    (Linux ``/proc/net/tcp``), bytes; None when it cannot be found."""
    try:
        family = sock.family
        ours = _proc_address(sock.getsockname(), family)
        theirs = _proc_address(sock.getpeername(), family)
        table = "/proc/net/tcp6" if family == socket.AF_INET6 else "/proc/net/tcp"
        with open(table, encoding="ascii") as fh:
            for line in fh:
                fields = line.split()
                if len(fields) > 4 and fields[1] == theirs and fields[2] == ours:
                    return int(fields[4].partition(":")[2], 16)
    except (OSError, ValueError, struct.error):
        return None
    return None


def _peer_window(sock: socket.socket) -> int | None:
    """The receive window the peer advertises, bytes (Linux ``TCP_INFO``; None elsewhere)."""
    option = getattr(socket, "TCP_INFO", None)
    if option is None:
        return None
    try:
        info = sock.getsockopt(socket.IPPROTO_TCP, option, _TCPI_SND_WND_AT + 4)
    except OSError:
        return None
    if len(info) < _TCPI_SND_WND_AT + 4:
        return None
    window: int = _TCPI_SND_WND.unpack_from(info, _TCPI_SND_WND_AT)[0]
    return window


def stream_line(report: dict[str, Any]) -> str:
    """One line on a finished stream (``summary.json`` ``igtl``)."""
    where = IgtlTarget(report["host"], report["port"]).text
    rate = report.get("send_rate_hz")
    at = "" if rate is None else f" at {rate:g} Hz"
    line = (
        f"OpenIGTLink {where}: sent {report['sent']} of {report['frames']} frames{at} "
        f"({report['dropped']} dropped)"
    )
    return line if report.get("error") is None else f"{line}; stopped: {report['error']}"
